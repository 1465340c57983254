"""NormalHedge / particle / grid-Bayes box filters on score maps, the face detector, the recipes."""

import numpy as np
import pytest

from vidtrack.errors import UsageError
from vidtrack.filters.score_trackers import (
    GridBayesBoxFilter,
    NormalHedgeBoxFilter,
    ParticleBoxFilter,
    score_at_centres,
)
from vidtrack.measure import face
from vidtrack.recipes.normalhedge import RECIPES
from vidtrack.recipes import build_tracker
from vidtrack.types import Box, Frame, ScoreMap

from conftest import synthetic_sequence

BOX_SIZE = (20.0, 20.0)


def peak_map(centre, around, *, height=1.0, width=3.0, clutter=None, shape=(61, 61)):
    """A score map over box positions in a window around ``around`` with a peak at box centre ``centre``."""
    origin = (around[0] - BOX_SIZE[0] / 2 - shape[1] // 2, around[1] - BOX_SIZE[1] / 2 - shape[0] // 2)
    smap = ScoreMap(np.zeros(shape), origin, 1.0, BOX_SIZE)
    c = smap.centers()
    d2 = (c[..., 0] - centre[0]) ** 2 + (c[..., 1] - centre[1]) ** 2
    scores = height * np.exp(-d2 / (2 * width ** 2))
    if clutter is not None:
        scores = np.maximum(scores, clutter)
    return ScoreMap(scores, origin, 1.0, BOX_SIZE, quality=float(scores.max()), stages={"score_map": scores})


def test_score_at_centres_reads_the_map_at_box_centres():
    rng = np.random.default_rng(0)
    smap = ScoreMap(rng.random((7, 9)), (10.0, 5.0), 2.0, (6.0, 4.0))
    centres = smap.centers()
    got = score_at_centres(smap, centres.reshape(-1, 2))
    assert np.allclose(got, smap.scores.ravel())
    # half-way between two cells: the average; far outside: the fill value
    mid = (centres[3, 4] + centres[3, 5]) / 2
    assert score_at_centres(smap, mid[None])[0] == pytest.approx(smap.scores[3, 4:6].mean())
    assert score_at_centres(smap, np.array([[-500.0, -500.0]]), outside=-7.0)[0] == -7.0


FILTERS = [NormalHedgeBoxFilter, ParticleBoxFilter, GridBayesBoxFilter]


@pytest.mark.parametrize("cls", FILTERS)
def test_filter_follows_a_moving_peak(cls):
    frame = Frame(0, np.zeros((240, 320, 3), np.uint8))
    start = np.array([100.0, 120.0])
    f = cls(rng=np.random.default_rng(0))
    f.initialize(Box.from_center(*start, *BOX_SIZE), frame)
    errors = []
    for t in range(1, 60):
        truth = start + np.array([1.0, 0.5]) * t
        prior = f.predict()
        post = f.update(peak_map(truth, prior.box.center))
        errors.append(np.hypot(*(post.box.center - truth)))
        assert post.status == "tracking" and 0.0 <= post.confidence <= 1.0
        particles = post.stages["particles"]
        assert particles.ndim == 2 and particles.shape[1] == 3 and np.all(particles[:, 2] >= 0)
    assert np.mean(errors[-20:]) < 3.0


@pytest.mark.parametrize("cls", FILTERS)
def test_no_evidence_means_lost_at_the_prediction(cls):
    frame = Frame(0, np.zeros((240, 320, 3), np.uint8))
    f = cls(rng=np.random.default_rng(0))
    f.initialize(Box.from_center(100.0, 100.0, *BOX_SIZE), frame)
    for _ in range(5):
        f.update(peak_map((100.0, 100.0), f.predict().box.center))
    prior = f.predict()
    flat = peak_map((100.0, 100.0), prior.box.center, height=0.1)   # peak score 0.1: no good evidence
    post = f.update(flat)
    assert post.status == "lost" and post.box == prior.box and post.confidence < 0.5
    post = f.update(None)
    assert post.status == "lost"


def test_nh_resists_a_clutter_burst_better_than_its_scale():
    # A strong false peak appearing for one frame far from the target must not drag NH there.
    frame = Frame(0, np.zeros((240, 320, 3), np.uint8))
    f = NormalHedgeBoxFilter(rng=np.random.default_rng(1))
    truth = np.array([150.0, 120.0])
    f.initialize(Box.from_center(*truth, *BOX_SIZE), frame)
    for _ in range(20):
        f.update(peak_map(truth, f.predict().box.center))
    prior = f.predict()
    smap = peak_map(truth, prior.box.center)
    c = smap.centers()
    clutter = 1.0 * np.exp(-((c[..., 0] - truth[0] - 25) ** 2 + (c[..., 1] - truth[1]) ** 2) / 18.0)
    post = f.update(ScoreMap(np.maximum(smap.scores, clutter), smap.origin, 1.0, BOX_SIZE, quality=1.0))
    assert np.hypot(*(post.box.center - truth)) < 5.0


def test_nh_scalars_and_confidence_from_concentration():
    frame = Frame(0, np.zeros((240, 320, 3), np.uint8))
    f = NormalHedgeBoxFilter(rng=np.random.default_rng(0))
    f.initialize(Box.from_center(100.0, 100.0, *BOX_SIZE), frame)
    post = None
    for _ in range(10):
        post = f.update(peak_map((100.0, 100.0), f.predict().box.center))
    assert post.scalars["c_t"] > 0 and 1 <= post.scalars["live_actions"] <= f.n_actions
    assert post.confidence > 0.5
    weights = post.stages["particles"][:, 2]
    assert weights.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("name", ["nh", "pf", "bayes"])
def test_recipes_track_the_synthetic_target_and_show_stages(name):
    frames, boxes = synthetic_sequence(n=25)
    tracker = build_tracker(name, seed=0, detector="ncc")
    tracker.initialize(frames[0], boxes[0])
    states = [tracker.step(f) for f in frames[1:]]
    assert "score_map" in states[-1].stages and states[-1].stages["particles"].shape[1] == 3
    errors = [np.hypot(*(s.box.center - b.center)) for s, b in zip(states, boxes[1:])]
    assert np.mean(errors[-10:]) < 6.0
    if name == "nh":
        assert {"c_t", "live_actions"} <= set(states[-1].scalars)


def test_unknown_detector_and_option_raise_usage_error():
    for name in RECIPES:
        with pytest.raises(UsageError):
            build_tracker(name, seed=0, detector="nope")
        with pytest.raises(UsageError):
            build_tracker(name, seed=0, bogus=1)


def test_face_detector_without_cascade_is_a_usage_error(monkeypatch, tmp_path):
    monkeypatch.setenv("VIDTRACK_FACE_CASCADE", str(tmp_path / "missing.xml"))
    monkeypatch.setattr(face.cv2.data, "haarcascades", str(tmp_path), raising=False)
    with pytest.raises(UsageError, match="cascade"):
        build_tracker("nh", seed=0, detector="face")


def test_face_score_map_from_detections():
    # A fake detector firing on the true face box (strong) and on clutter (weak).
    truth = Box(60, 40, 30, 30)

    def detect(gray):
        x0, y0 = detect.offset
        return (np.array([[truth.x - x0, truth.y - y0, 30, 30], [5, 5, 30, 30]], float), np.array([0.9, 0.3]))

    measurer = face.FaceScoreMapMeasurer(step=1.0, detect=detect)
    frame = Frame(0, np.zeros((160, 200, 3), np.uint8))
    measurer.initialize(frame, truth)
    prior_box = Box(64, 44, 30, 30)
    region = face.search_window(prior_box, measurer.margin, 200, 160)
    detect.offset = (int(region.x), int(region.y))
    from vidtrack.types import Estimate

    smap = measurer.measure(frame, Estimate(prior_box))
    r, c = np.unravel_index(np.argmax(smap.scores), smap.scores.shape)
    best = smap.box_at(r, c)
    assert abs(best.x - truth.x) <= 1 and abs(best.y - truth.y) <= 1
    assert smap.quality == pytest.approx(0.9)
    assert smap.stages["detections"].shape == (2, 3)


@pytest.mark.parametrize("name", ["nh-face", "pf-face", "bayes-face"])
def test_face_recipes_follow_faceocc1(name):
    """The ``-face`` recipes (what ``vidtrack eval --filter nh-face`` runs) follow a real face."""
    from conftest import SEQUENCES
    from vidtrack.eval.datasets import load_sequence
    from vidtrack.sources import ImageFolderSource

    folder = SEQUENCES / "FaceOcc1"
    if not folder.is_dir():
        pytest.skip("shared benchmark sequences not present")
    sequence = load_sequence(folder)
    tracker = build_tracker(name, seed=0)
    frames = iter(ImageFolderSource(sequence.path, files=list(sequence.files[:40])))
    tracker.initialize(next(frames), sequence.to_pixels(sequence.ground_truth_box(0)))
    errors = [np.hypot(*(tracker.step(frame).box.center - sequence.to_pixels(sequence.ground_truth_box(row)).center))
              for row, frame in enumerate(frames, start=1)]
    assert np.mean(errors) < 15.0
