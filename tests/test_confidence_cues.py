"""The confidence cues of the score-map trackers and cbt: appearance verification and the calibrated files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vidtrack.eval.confidence import roc_auc
from vidtrack.eval.metrics import iou
from vidtrack.filters import cbt as cbt_filter
from vidtrack.filters import mil as mil_filter
from vidtrack.filters import score_trackers
from vidtrack.filters.calibration import Calibration, load_calibration
from vidtrack.filters.confidence_cues import border_cues, map_value, verification_cues
from vidtrack.measure.verification import AppearanceVerifier, VerifiedMeasurer
from vidtrack.recipes import build_tracker
from vidtrack.types import TRACKING, Box, Detections, Estimate, Frame, ScoreMap, Superpixels

from conftest import synthetic_sequence


def _around(box: Box, boxes: float) -> Box:
    """The region of box positions reaching ``boxes`` box sizes on each side of ``box``."""
    return Box(box.x - boxes * box.w, box.y - boxes * box.h, box.w * (1 + 2 * boxes), box.h * (1 + 2 * boxes))


def test_verification_is_high_on_the_target_and_falls_when_the_box_leaves_it():
    frames, boxes = synthetic_sequence(n=20, size=(200, 150))
    verifier = AppearanceVerifier()
    verifier.initialize(frames[0], boxes[0])
    box = boxes[15]                                  # the target 15 frames later, elsewhere in the frame
    vmap = verifier.verify(frames[15].image, _around(box, 1.5), box.size)
    assert isinstance(vmap, ScoreMap) and vmap.stages["colour"].shape == vmap.scores.shape
    on = verification_cues({"verification": vmap}, box.center)
    assert on["verify"] > 0.8 and on["verify_gap"] < 0.1
    for dx, dy in ((1.2, 0.0), (0.0, -1.2), (0.8, 0.8)):     # beside the target: background in the box
        centre = box.center + np.array([dx * box.w, dy * box.h])
        off = verification_cues({"verification": vmap}, centre)
        assert off["verify"] < on["verify"] - 0.4 and off["verify_gap"] > 0.4
        assert off["colour"] < on["colour"]
    # the template stays the first frame's: the map's best position is the target's
    r, c = np.unravel_index(np.argmax(vmap.scores), vmap.scores.shape)
    assert np.hypot(*(vmap.box_at(r, c).center - box.center)) < 3.0


def test_the_size_gap_is_positive_for_a_box_of_the_wrong_size():
    class SizeOfThePrior:   # a measurer stating no box size: the verification takes the prior's
        def initialize(self, frame, box):
            pass

        def measure(self, frame, prior):
            return Detections(points=np.zeros((0, 2)), scores=np.zeros(0))

    frames, boxes = synthetic_sequence(n=20, size=(200, 150))
    measurer = VerifiedMeasurer(SizeOfThePrior())
    measurer.initialize(frames[0], boxes[0])
    box = boxes[15]
    gaps = {}
    for factor in (0.6, 1.0, 1.6):     # a prior (and so a measured size) too small, right, too large
        prior = Estimate(Box.from_center(*box.center, *(factor * box.size)), None, 1.0, TRACKING)
        stages = measurer.measure(frames[15], prior).stages
        assert len(stages["verification"].stages["sizes"]) == len(measurer.size_factors)
        gaps[factor] = verification_cues(stages, box.center)["verify_size_gap"]
    assert gaps[1.0] < 0.0                         # the first frame's size matches best at the target
    assert gaps[0.6] > 0.1 and gaps[1.6] > 0.1     # a larger (smaller) box at the same centre matches better


def test_the_map_reaches_a_measured_box_far_from_the_prior():
    """A re-detection moves the measured box several box sizes from the prior: the map covers it, so the cues
    at the box are the target's, not the map's clamped edge."""
    class ReDetecting:   # a measurer that states its box (as mil's does): the target, wherever the prior is
        def initialize(self, frame, box):
            pass

        def measure(self, frame, prior):
            return Superpixels(labels=np.zeros((1, 1), np.int32), features=np.zeros((1, 1)), scores=np.ones(1),
                               inliers=np.ones(1, bool), box=self.box)

    frames, boxes = synthetic_sequence(n=20, size=(200, 150))
    inner = ReDetecting()
    measurer = VerifiedMeasurer(inner, size_factors=())
    measurer.initialize(frames[0], boxes[0])
    box = boxes[15]
    inner.box = box
    far = Estimate(Box.from_center(box.center[0] - 3 * box.w, box.center[1], *box.size), None, 1.0, TRACKING)
    vmap = measurer.measure(frames[15], far).stages["verification"]
    region = vmap.search_region
    for centre in (box.center, far.box.center):          # both the measured box and the prior are on the map
        assert region.x <= centre[0] - box.w / 2 and centre[0] + box.w / 2 <= region.x + region.w
    near = measurer.measure(frames[15], Estimate(box, None, 1.0, TRACKING)).stages["verification"]
    on_target = verification_cues({"verification": near}, box.center)["verify"]
    assert on_target > 0.5
    assert verification_cues({"verification": vmap}, box.center)["verify"] == pytest.approx(on_target, abs=0.1)


@pytest.mark.parametrize("name", ["nh", "pf", "bayes"])
def test_the_score_map_trackers_verify_gap_sees_the_target_two_box_sizes_away(name):
    """A box resting 1.7 box sizes beside the target: the score-map trackers' map reaches the target, so
    ``verify_gap`` says a better match lies nearby; a map reaching one box size does not see it."""
    frames, boxes = synthetic_sequence(n=20, size=(200, 150))
    measurer = build_tracker(name, seed=0).measurer
    measurer.initialize(frames[0], boxes[0])
    box = boxes[15]
    checked = 0
    for dx, dy in ((1.7, 0.0), (-1.7, 0.0), (0.0, 1.7), (0.0, -1.7)):
        beside = Box.from_center(box.center[0] + dx * box.w, box.center[1] + dy * box.h, *box.size)
        if beside.x < 0 or beside.y < 0 or beside.x + beside.w > 200 or beside.y + beside.h > 150:
            continue
        checked += 1
        prior = Estimate(beside, None, 1.0, TRACKING)
        wide = measurer.measure(frames[15], prior).stages
        narrow = VerifiedMeasurer(measurer.inner, margin=1.0)
        narrow.verifier = measurer.verifier
        near = narrow.measure(frames[15], prior).stages
        assert verification_cues(wide, beside.center)["verify_gap"] > 0.4
        assert verification_cues(near, beside.center)["verify_gap"] < verification_cues(wide, beside.center)["verify_gap"] - 0.2
    assert checked >= 1


def test_map_value_is_bilinear_and_clamped_to_the_map():
    smap = ScoreMap(scores=np.array([[0.0, 1.0], [2.0, 3.0]]), origin=(10.0, 20.0), step=2.0, box_size=(4.0, 6.0))
    assert map_value(smap.scores, smap, (13.0, 24.0)) == pytest.approx(1.5)   # cell (0.5, 0.5)
    assert map_value(smap.scores, smap, (0.0, 0.0)) == pytest.approx(0.0)     # off the map: its corner
    assert map_value(smap.scores, smap, (99.0, 99.0)) == pytest.approx(3.0)


def test_the_border_gap_is_the_distance_to_the_nearest_edge_in_box_sizes():
    frame = (100, 80)                     # (width, height)
    box_size = np.sqrt(8 * 18)            # the gap is in units of sqrt(w h) = 12 px
    assert border_cues(Box(40, 30, 8, 18), frame)["border_gap"] == pytest.approx(30 / box_size)   # top, 30 px
    assert border_cues(Box(86, 30, 8, 18), frame)["border_gap"] == pytest.approx(6 / box_size)    # right, 6 px
    assert border_cues(Box(40, 59, 8, 18), frame)["border_gap"] == pytest.approx(3 / box_size)    # bottom, 3 px
    assert border_cues(Box(-4, 30, 8, 18), frame)["border_gap"] == 0.0                            # across the left
    assert border_cues(Box(-10, -10, 120, 100), frame)["border_gap"] == 0.0                       # over the frame
    assert border_cues(Box(40, 30, 8, 18), None) == {}


@pytest.mark.parametrize("name", ["mil", "nh", "pf", "bayes", "cbt"])
def test_every_filter_reports_the_border_gap_of_its_box(name):
    frames, boxes = synthetic_sequence(n=4)
    tracker = build_tracker(name, seed=0)
    tracker.initialize(frames[0], boxes[0])
    centre_filter = getattr(tracker.filter, "inner", tracker.filter)   # the box the cues are read at
    for frame in frames[1:]:
        state = tracker.step(frame)
        height, width = frame.image.shape[:2]
        expected = border_cues(centre_filter.estimate.box, (width, height))["border_gap"]
        assert state.scalars["border_gap"] == pytest.approx(expected) and expected > 0.5


def test_the_verified_measurer_only_adds_the_verification_stage():
    frames, boxes = synthetic_sequence(n=6)
    plain = build_tracker("nh", seed=0).measurer.inner
    wrapped = VerifiedMeasurer(build_tracker("nh", seed=0).measurer.inner)
    plain.initialize(frames[0], boxes[0])
    wrapped.initialize(frames[0], boxes[0])
    for frame, box in zip(frames[1:], boxes[1:]):
        prior = Estimate(box, None, 1.0, TRACKING)
        a, b = plain.measure(frame, prior), wrapped.measure(frame, prior)
        assert np.array_equal(a.scores, b.scores) and a.origin == b.origin and a.quality == b.quality
        assert set(b.stages) == set(a.stages) | {"verification"}
        plain.learn(frame, prior)
        wrapped.learn(frame, prior)


def _vanishing_clip(n: int = 40, gone: int = 20):
    """The synthetic target, which vanishes at frame ``gone`` (the ground truth keeps moving)."""
    frames, boxes = synthetic_sequence(n=n, size=(200, 150), velocity=(2.0, 0.5))
    blank, _ = synthetic_sequence(n=1, size=(200, 150), box=(0, 0, 1, 1))   # the background (and one pixel)
    frames = [f if k < gone else Frame(k, blank[0].image.copy()) for k, f in enumerate(frames)]
    return frames, boxes


@pytest.mark.parametrize("name", ["nh", "pf", "bayes", "cbt"])
def test_calibrated_confidence_ranks_the_lost_frames_below_the_tracked_ones(name):
    frames, boxes = _vanishing_clip()
    runs = {}
    for confidence in (name, None):
        tracker = build_tracker(name, seed=0, confidence=confidence)
        tracker.initialize(frames[0], boxes[0])
        runs[confidence] = [tracker.step(f) for f in frames[1:]]
    states = runs[name]
    # the calibration changes the confidence only: the boxes and the status are the uncalibrated tracker's
    assert [s.box.as_array().tolist() for s in states] == [s.box.as_array().tolist() for s in runs[None]]
    assert [s.status for s in states] == [s.status for s in runs[None]]
    overlap = iou(np.array([s.box.as_array() for s in states]), np.array([b.as_array() for b in boxes[1:]]))
    good = overlap > 0.5
    assert good[:15].all() and not good[-10:].any()
    confidence = np.array([s.confidence for s in states])
    assert roc_auc(confidence, good) > 0.9
    assert np.median(confidence[good]) > 0.5 > np.median(confidence[-10:])
    assert {"verify", "verify_gap", "colour", "coast"} <= set(states[-1].scalars)


@pytest.mark.parametrize(("name", "cues"), [("mil", mil_filter.CUES), ("nh", score_trackers.CUES),
                                            ("pf", score_trackers.CUES), ("bayes", score_trackers.CUES),
                                            ("cbt", cbt_filter.CUES)])
def test_every_cue_of_a_trackers_table_is_one_its_frames_carry(name, cues):
    # a cue the tracker never computes would be fitted (and selected) on its fill value alone
    frames, boxes = _vanishing_clip()
    tracker = build_tracker(name, seed=0)
    tracker.initialize(frames[0], boxes[0])
    carried = set()
    for frame in frames[1:]:
        carried |= set(tracker.step(frame).scalars)
    assert {c[0] for c in cues} <= carried, sorted({c[0] for c in cues} - carried)


@pytest.mark.parametrize(("name", "cues"), [("nh", score_trackers.CUES), ("pf", score_trackers.CUES),
                                            ("bayes", score_trackers.CUES), ("cbt", cbt_filter.CUES)])
def test_packaged_files_round_trip_and_name_their_filters_cues(name, cues, tmp_path):
    cal = load_calibration(name)
    assert set(cal.cues) <= {c[0] for c in cues} and 0.0 < cal.lost_below < 1.0
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(cal.to_dict()), encoding="utf-8")
    again = Calibration.from_dict(json.loads(path.read_text(encoding="utf-8")))
    assert again.cues == cal.cues and again.lost_below == cal.lost_below
    rng = np.random.default_rng(0)
    for _ in range(5):
        cue = {c[0]: float(rng.uniform(c[2], c[3])) for c in cues}
        assert again.probability(cue) == pytest.approx(cal.probability(cue), abs=1e-6)
