"""Multiple Instance Filtering: measurement of a known inlier set, the Kalman filter, a synthetic track."""

import pickle
import subprocess
import sys

import cv2
import numpy as np
import pytest

import vidtrack
from vidtrack.config import with_settings
from vidtrack.errors import UsageError
from vidtrack.filters.mil import KalmanConfig, MILKalmanFilter, box_from_state, state_from_box
from vidtrack.measure import superpixels as sp
from vidtrack.measure.mil import inlier_measurement, locate_inliers
from vidtrack.measure.mil_fusion import MILMeasurer
from vidtrack.measure.threads import SecondThread
from vidtrack.measure.verification import VerifiedMeasurer
from vidtrack.recipes import build_tracker, recipe_config
from vidtrack.recipes.mil import build_mil
from vidtrack.types import LOST, TRACKING, Box, Estimate, Frame, Superpixels


def test_measurement_of_a_known_inlier_set():
    # a 4x4 grid of 10x10 superpixels; inliers are the 2x3 block at columns 1-3, rows 1-2
    labels = np.repeat(np.repeat(np.arange(16).reshape(4, 4), 10, axis=0), 10, axis=1)
    inliers = np.zeros(16, bool)
    inliers[[5, 6, 7, 9, 10, 11]] = True
    centre, size, mass = inlier_measurement(labels, inliers)
    assert mass == 600
    assert centre == pytest.approx([25.0, 20.0])  # pixels 10..39 x 10..29 -> centre (25, 20)
    assert size == pytest.approx([30.0, 20.0], abs=0.05)  # sqrt(12 var + 1) of a uniform run
    located = locate_inliers(labels, inliers.astype(float), np.array([30.0, 20.0]), np.array([22.0, 18.0]))
    assert located[0] == pytest.approx([25.0, 20.0], abs=0.6)
    assert inlier_measurement(labels, np.zeros(16, bool)) is None


def test_state_box_round_trip():
    box = Box(10, 20, 30, 40)
    assert box_from_state(state_from_box(box)) == box


def _superpixels(box, quality=1.0):
    return Superpixels(labels=np.zeros((2, 2), int), features=np.zeros((1, 1)), scores=np.array([1.0]),
                       inliers=np.array([box is not None]), box=box, quality=quality)


#: the Kalman filter's own rule for the status (lost when not measured), without the calibrated confidence
RAW = KalmanConfig(confidence=None)


def test_filter_follows_measurements_and_predicts_when_no_inliers():
    f = MILKalmanFilter(RAW)
    f.initialize(Box(100, 100, 20, 20))
    for k in range(1, 30):  # constant velocity 2 px/frame in x
        f.predict()
        est = f.update(_superpixels(Box(100 + 2 * k, 100, 20, 20)))
        assert est.status == "tracking"
    assert f.x_[1] == pytest.approx(2.0, abs=0.3)
    prior = f.predict()
    lost = f.update(_superpixels(None, quality=0.0))
    assert lost.status == "lost"
    assert lost.box.x == pytest.approx(prior.box.x)
    assert lost.confidence < 0.5
    assert f.update(None).status == "lost"
    # Joseph form keeps P symmetric positive definite
    assert np.allclose(f.P_, f.P_.T)
    assert np.all(np.linalg.eigvalsh(f.P_) > 0)


def test_descriptors_and_feature_map():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (40, 60, 3), dtype=np.uint8)
    labels = sp.slic_labels(img, region_size=8)
    K = labels.max() + 1
    desc = sp.superpixel_descriptors(img, labels)
    assert desc.shape[0] == K and np.all(desc >= 0) and np.all(desc <= 1 + 1e-9)
    # the explicit map approximates the additive chi2 kernel k(x, y) = sum 2 x y / (x + y)
    x, y = desc[0], desc[1]
    exact = np.sum(np.where(x + y > 0, 2 * x * y / np.maximum(x + y, 1e-12), 0.0))
    approx = sp.chi2_feature_map(x[None], order=2)[0] @ sp.chi2_feature_map(y[None], order=2)[0]
    assert approx == pytest.approx(exact, rel=0.05)
    pairs, lengths = sp.adjacency(labels)
    assert np.all(pairs[:, 0] < pairs[:, 1]) and np.all(lengths > 0)


def _scene(index, cx, cy):
    rng = np.random.default_rng(100 + index)
    img = np.empty((120, 160, 3), np.uint8)
    img[:] = (60, 140, 60)
    img += rng.integers(0, 20, img.shape, dtype=np.uint8)
    x0, y0 = int(cx - 12), int(cy - 12)
    img[y0:y0 + 24, x0:x0 + 24] = (30, 40, 220)  # red square with a stripe
    img[y0 + 8:y0 + 16, x0:x0 + 24] = (220, 220, 40)
    return Frame(index, img)


def test_mil_tracks_a_moving_square_and_exposes_stages():
    tracker = build_tracker("mil", seed=0)
    tracker.initialize(_scene(0, 50, 60), Box(38, 48, 24, 24))
    state = None
    for k in range(1, 25):
        state = tracker.step(_scene(k, 50 + 2 * k, 60 + k))
    truth = np.array([50 + 2 * 24, 60 + 24])
    assert np.linalg.norm(state.box.center - truth) < 6
    assert state.status == "tracking"
    for name in ("superpixels", "svm_scores", "inliers"):
        assert name in state.stages
    assert state.stages["superpixels"].shape == state.stages["inliers"].shape
    for name in ("inlier_count", "svm_margin", "covariance_trace"):
        assert name in state.scalars


def _behind_the_post(speed, seed=0, settings=None, post=24):
    """A 24-pixel square passes behind a grey post ``post`` pixels wide: the states, whether each frame hides it
    wholly, the last centre."""
    def scene(index, cx):
        img = _scene(index, cx, 60).image
        img[:, 80:80 + post] = (128, 128, 128)
        return Frame(index, img)

    tracker = build_tracker("mil", seed=seed, settings=settings)
    tracker.initialize(scene(0, 30), Box(18, 48, 24, 24))
    last = int((64 + post) / speed)
    states, hidden = [], []
    for k in range(1, last + 1):
        cx = 30 + speed * k
        states.append(tracker.step(scene(k, cx)))
        hidden.append(80 <= cx - 12 and cx + 12 <= 80 + post)   # entirely behind the post
    return states, hidden, 30 + speed * last


def test_mil_is_lost_while_the_target_is_wholly_behind_an_occluder():
    """A frame in which the square is entirely hidden is only predicted, and its calibrated confidence says the
    box is unlikely to be on the target (below one half); with the uncalibrated rule (lost = not measured, a
    half-hidden square that the correlation filter still sees is not) it is lost."""
    hidden_frames = 0
    for speed in (1.8, 2.0, 2.2):
        states, hidden, _ = _behind_the_post(speed)
        for state, wholly in zip(states, hidden):
            if wholly:
                hidden_frames += 1
                assert state.scalars["measured"] == 0.0 and state.confidence < 0.5
    assert hidden_frames >= 1
    states, hidden, _ = _behind_the_post(2.0, settings={"kalman.confidence": None})
    assert all(state.status == "lost" for state, wholly in zip(states, hidden) if wholly) and any(hidden)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mil_reacquires_a_target_that_emerges_from_behind_an_occluder(seed):
    """The inliers' coverage falls as the post covers the square: the filter takes it for an occlusion, carries
    the box through at the velocity of the last wholly visible frame, and measures the square again as it
    emerges, at every speed."""
    for speed in (1.8, 2.0, 2.2):
        states, _, centre = _behind_the_post(speed, seed=seed)
        assert any(state.scalars.get("occluded") for state in states)
        assert states[-1].status == "tracking" and abs(states[-1].box.center[0] - centre) < 6, speed


@pytest.mark.parametrize("speed", [1.8, 2.2])
def test_without_occlusion_reasoning_mil_stays_behind_a_post_wider_than_the_target(speed):
    """A post a third wider than the square hides it wholly for a few frames: with the occlusion reasoning the
    box is carried through and the square found again; without it the measurements of the half-hidden square
    pull the box back onto the post, and it is not found again (what the reasoning is for)."""
    states, _, centre = _behind_the_post(speed, post=32)
    assert states[-1].status == "tracking" and abs(states[-1].box.center[0] - centre) < 6
    states, _, centre = _behind_the_post(speed, post=32, settings={"kalman.occlusion_below": None})
    assert abs(states[-1].box.center[0] - centre) > 24


def test_pegasos_iterate_averaging_scores_with_the_mean_iterate():
    from vidtrack.learn.pegasos import PegasosSVM

    rng = np.random.default_rng(1)
    X = np.vstack([rng.normal(1.0, 0.3, (50, 3)), rng.normal(-1.0, 0.3, (50, 3))])
    y = np.r_[np.ones(50), -np.ones(50)]
    plain = PegasosSVM(lam=1e-2, batch_size=10, n_iter=30, rng=5).partial_fit(X, y)
    avg = PegasosSVM(lam=1e-2, batch_size=10, n_iter=30, rng=5, average=True).partial_fit(X, y)
    assert np.allclose(plain.coef_, avg.coef_)  # training is unchanged
    assert not np.allclose(plain.decision_function(X), avg.decision_function(X))
    assert np.allclose(avg.decision_function(X), X @ avg.avg_coef_[:-1] + avg.avg_coef_[-1])
    assert np.mean(np.sign(avg.decision_function(X)) == y) == 1.0


def _textured_scene(size_wh, centre, patch, shape=(240, 320)):
    """A smooth background with ``patch`` resized to ``size_wh`` centred at ``centre`` (clipped at the border)."""
    bg_rng = np.random.default_rng(21)
    coarse = bg_rng.random((shape[0] // 16 + 2, shape[1] // 16 + 2, 3)).astype(np.float32)
    img = np.clip(60 + 120 * cv2.resize(coarse, shape[::-1], interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)
    w, h = max(int(round(size_wh[0])), 2), max(int(round(size_wh[1])), 2)
    target = cv2.resize(patch, (w, h), interpolation=cv2.INTER_LINEAR)
    x0, y0 = int(round(centre[0] - w / 2)), int(round(centre[1] - h / 2))
    xs, ys = max(x0, 0), max(y0, 0)
    xe, ye = min(x0 + w, shape[1]), min(y0 + h, shape[0])
    if xe > xs and ye > ys:
        img[ys:ye, xs:xe] = target[ys - y0:ye - y0, xs - x0:xe - x0]
    return img


def _target_patch(seed=3):
    rng = np.random.default_rng(seed)
    coarse = rng.random((10, 8, 3)).astype(np.float32)
    return np.clip(255 * cv2.resize(coarse, (32, 40), interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def test_mil_follows_a_target_that_grows_and_shrinks_by_2x():
    patch = _target_patch()
    centre, base = np.array([160.0, 120.0]), np.array([30.0, 36.0])
    frames = 90
    sizes = [base * 2.0 ** (k / frames) for k in range(frames + 1)]                 # grows 2x ...
    sizes += [base * 2.0 ** (1 - k / frames) for k in range(1, frames + 1)]         # ... and shrinks back
    tracker = build_tracker("mil", seed=0)
    tracker.initialize(Frame(0, _textured_scene(sizes[0], centre, patch)), Box.from_center(*centre, *sizes[0]))
    widths = {}
    for k, size in enumerate(sizes[1:], start=1):
        state = tracker.step(Frame(k, _textured_scene(size, centre, patch)))
        widths[k] = (state.box.w / size[0], state.box.h / size[1])
    assert np.allclose(widths[frames], 1.0, atol=0.1)          # at twice the size
    assert np.allclose(widths[2 * frames], 1.0, atol=0.1)      # and back at the start size


def test_mil_redetects_a_target_that_leaves_and_reenters_the_frame():
    patch = _target_patch(5)
    size = np.array([30.0, 36.0])
    path = [np.array([200.0 + 6 * k, 120.0]) for k in range(25)]          # walks out through the right border
    path += [np.array([400.0, 120.0])] * 20                               # out of view
    path += [np.array([90.0, 150.0])] * 25                                # re-enters elsewhere and stays
    tracker = build_tracker("mil", seed=0)
    tracker.initialize(Frame(0, _textured_scene(size, path[0], patch)), Box.from_center(*path[0], *size))
    states = [tracker.step(Frame(k, _textured_scene(size, c, patch))) for k, c in enumerate(path[1:], start=1)]
    out_of_view = states[30:44]
    assert sum(s.status == "lost" for s in out_of_view) >= 0.8 * len(out_of_view)
    last = states[-5:]
    assert all(s.status == "tracking" for s in last)
    assert all(np.linalg.norm(s.box.center - path[-1]) < 0.25 * np.sqrt(size.prod()) for s in last)


def test_the_second_thread_gives_the_same_track_as_one_thread():
    """The correlation filter on a second thread only overlaps it with the superpixels: boxes and statuses are
    identical, through a loss and a re-detection."""
    patch = _target_patch(5)
    size = np.array([30.0, 36.0])
    path = [np.array([200.0 + 6 * k, 120.0]) for k in range(25)] + [np.array([90.0, 150.0])] * 15
    tracks = {}
    for threads in (False, True):
        tracker = build_mil(recipe_config("mil"), seed=0, threads=threads)
        tracker.initialize(Frame(0, _textured_scene(size, path[0], patch)), Box.from_center(*path[0], *size))
        states = [tracker.step(Frame(k, _textured_scene(size, c, patch))) for k, c in enumerate(path[1:], start=1)]
        tracks[threads] = [(s.box.x, s.box.y, s.box.w, s.box.h, s.status) for s in states]
    assert any(s[-1] == "lost" for s in tracks[False])     # the path covers a loss and a re-detection
    assert tracks[True] == tracks[False]


@pytest.mark.parametrize("enabled", [False, True])
def test_second_thread_runs_tasks_in_order_and_raises_where_the_result_is_taken(enabled):
    worker = SecondThread(enabled)
    done = []
    tasks = [worker.submit(done.append, k) for k in range(5)]
    failed = worker.submit(lambda: 1 / 0)
    assert [t.result() for t in tasks] == [None] * 5 and done == list(range(5))
    with pytest.raises(ZeroDivisionError):
        failed.result()
    copy = pickle.loads(pickle.dumps(worker))      # without its thread, which starts again on demand
    assert copy.enabled is enabled and copy.submit(sum, [1, 2]).result() == 3
    worker.close()


def test_a_predicted_frame_the_correlation_filter_confirms_is_not_lost():
    f = MILKalmanFilter(RAW)
    f.initialize(Box(100, 100, 20, 20))
    f.predict()
    f.update(_superpixels(Box(102, 100, 20, 20)))
    twin = MILKalmanFilter(RAW)
    twin.initialize(Box(100, 100, 20, 20))
    twin.predict()
    twin.update(_superpixels(Box(102, 100, 20, 20)))
    f.predict(), twin.predict()
    absent = _superpixels(None, quality=0.0)
    present = Superpixels(labels=absent.labels, features=absent.features, scores=absent.scores,
                          inliers=absent.inliers, box=None, quality=0.0, present=True)
    lost, kept = f.update(absent), twin.update(present)
    assert lost.status == "lost" and kept.status == "tracking"
    assert kept.box == lost.box and kept.confidence == lost.confidence     # predicted only, the same way
    assert kept.scalars["measured"] == 0.0 and lost.scalars["measured"] == 0.0


def test_present_changes_only_the_reported_status():
    """Behind the post the filter is predicted only either way; with fusion.present fewer of those frames say lost."""
    def scene(index, cx):
        img = _scene(index, cx, 60).image
        img[:, 80:104] = (128, 128, 128)
        return Frame(index, img)

    runs = {}
    for present in (None, 0.5):
        tracker = build_tracker("mil", seed=0, settings={"fusion.present": present, "kalman.confidence": None})
        tracker.initialize(scene(0, 30), Box(18, 48, 24, 24))
        runs[present] = [tracker.step(scene(k, 30 + 2.2 * k)) for k in range(1, 41)]
    assert [s.box for s in runs[None]] == [s.box for s in runs[0.5]]
    lost = {p: sum(s.status == "lost" for s in states) for p, states in runs.items()}
    assert lost[None] > 0 and lost[0.5] <= lost[None]
    for a, b in zip(runs[None], runs[0.5]):
        assert a.status == b.status or (a.status == "lost" and b.status == "tracking")


def test_mil_paper_tracks_with_the_superpixels_alone():
    """``mil-paper`` is the paper's tracker: no correlation filter (no correlation stage, the size measured
    by the inliers), and a target wholly behind an occluder is lost."""
    tracker = vidtrack.create("mil-paper", seed=0)
    tracker.init(_scene(0, 50, 60).image, (38, 48, 24, 24))
    for k in range(1, 25):
        ok, box = tracker.update(_scene(k, 50 + 2 * k, 60 + k).image)
    assert ok and np.linalg.norm(tracker.state.box.center - (50 + 2 * 24, 60 + 24)) < 6
    assert tracker.tracker.measurer.cf_ is None
    assert "correlation" not in tracker.state.stages and "svm_scores" in tracker.state.stages

    def behind_the_post(index, cx):
        img = _scene(index, cx, 60).image
        img[:, 80:104] = (128, 128, 128)
        return img

    paper = vidtrack.create("mil-paper", seed=0)
    paper.init(behind_the_post(0, 30), (18, 48, 24, 24))
    hidden = []
    for k in range(1, 41):
        cx = 30 + 2.0 * k
        ok, _ = paper.update(behind_the_post(k, cx))
        if 80 <= cx - 12 and cx + 12 <= 104:
            hidden.append(ok)
    assert hidden and not any(hidden)


def test_the_fusion_settings_of_mil_paper_turn_the_correlation_filter_off():
    settings = {"fusion.refine": "false", "fusion.size_from": "inliers"}
    tracker = build_tracker("mil", seed=0, settings=settings)
    tracker.initialize(_scene(0, 50, 60), Box(38, 48, 24, 24))
    assert tracker.measurer.inner.cf_ is None      # inside the appearance verification of the confidence
    assert recipe_config("mil-paper").fusion.uses_correlation is False
    with pytest.raises(UsageError, match="fusion.redetect"):
        build_tracker("mil", settings={"fusion.redetect_after": 3})


def test_the_command_line_runs_mil_paper(tmp_path):
    """``--filter mil-paper`` writes the boxes ``vidtrack.track(..., "mil-paper")`` yields."""
    folder = tmp_path / "frames"
    folder.mkdir()
    images = [_scene(k, 50 + 2 * k, 60 + k).image for k in range(12)]
    for k, image in enumerate(images):
        cv2.imwrite(str(folder / f"{k:04d}.png"), image)
    boxes = tmp_path / "boxes.txt"
    result = subprocess.run([sys.executable, "-m", "vidtrack", str(folder), "--init-box", "38,48,24,24",
                             "--filter", "mil-paper", "--boxes", str(boxes), "--quiet"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    written = np.loadtxt(boxes, delimiter=",")
    expected = [state.box.as_array() for state in vidtrack.track(images, (38, 48, 24, 24), "mil-paper", seed=0)]
    assert written.shape == (12, 4)
    assert np.allclose(written, expected, atol=0.01)


def test_the_confidence_reads_the_first_frames_appearance_without_moving_a_box():
    """With its calibration ``mil`` measures the appearance verification and reads its cues at the box; the
    boxes, on a clip never reported lost, are those of the tracker without it, and ``mil-paper`` (no
    calibration) does not measure it."""
    runs = {}
    for confidence in ("mil", None):
        tracker = build_tracker("mil", seed=0, settings={"kalman.confidence": confidence})
        tracker.initialize(_scene(0, 50, 60), Box(38, 48, 24, 24))
        states = [tracker.step(_scene(k, 50 + 2 * k, 60 + k)) for k in range(1, 15)]
        runs[confidence] = (tracker, states)
    tracker, states = runs["mil"]
    assert isinstance(tracker.measurer, VerifiedMeasurer) and not isinstance(runs[None][0].measurer, VerifiedMeasurer)
    assert {"verify", "verify_gap", "colour", "verify_mean", "colour_mean"} <= set(states[-1].scalars)
    assert states[-1].scalars["verify_mean"] > 0.5          # the box still looks like the first frame's target
    assert [s.box.as_array().tolist() for s in states] == [s.box.as_array().tolist() for s in runs[None][1]]
    assert not isinstance(build_tracker("mil-paper", seed=0).measurer, VerifiedMeasurer)
    assert all(s.status == "tracking" and s.confidence > 0.5 for s in states)   # an easy clip: never in doubt


def _measured_after_a_jump(settings, status, jump=30, *, blind=False):
    """``mil``'s measurer with ``settings`` learns a still square for three frames, then the square moves
    ``jump`` px right of the prediction, a prior of ``status``: the measurement.  ``blind``: the inliers
    measure nothing on that frame, at any search centre."""
    measurer = MILMeasurer(with_settings(recipe_config("mil"), settings), rng=0)
    measurer.initialize(_scene(0, 50, 60), Box(38, 48, 24, 24))
    for k in range(1, 4):
        measurer.measure(_scene(k, 50, 60), Estimate(Box(38, 48, 24, 24), covariance=np.eye(8)))
        measurer.learn(_scene(k, 50, 60), Estimate(Box(38, 48, 24, 24), scalars={"measured": 1.0}))
    if blind:
        measurer._inlier_stages = lambda found: (None, {})
    return measurer.measure(_scene(4, 50 + jump, 60), Estimate(Box(38, 48, 24, 24), covariance=np.eye(8),
                                                                status=status))


def _centre_found_after_a_jump(settings, status):
    """The centre measured after the square jumps 1.25 boxes (30 px) (:func:`_measured_after_a_jump`), or None."""
    z = _measured_after_a_jump(settings, status)
    return None if z is None or z.box is None else z.box.center


def test_a_frame_reported_lost_is_searched_as_an_unmeasured_one():
    """``fusion.search_when_lost`` (on in ``mil``): a prior the filter reports lost widens the search
    (the lost bag, the filter's re-detection), so a target 1.25 boxes from the prediction is found; from a
    prior reported tracking, or with the switch off, it is not (with ``fusion.recentre`` off, which would
    find it from any prior).  ``mil-paper`` searches as the paper does."""
    found = {(on, status): _centre_found_after_a_jump({"fusion.search_when_lost": on, "fusion.recentre": None},
                                                      status)
             for on in (True, False) for status in (LOST, TRACKING)}
    assert found[True, LOST] is not None and np.allclose(found[True, LOST], (80, 60), atol=2.0)
    assert found[True, TRACKING] is None and found[False, LOST] is None and found[False, TRACKING] is None
    assert recipe_config("mil").fusion.search_when_lost and not recipe_config("mil-paper").fusion.search_when_lost


def test_a_frame_without_inliers_is_searched_again_around_a_confident_filter_peak():
    """``fusion.recentre``: the target has moved 1.25 boxes from a prediction reported tracking, so the
    positive bag at the prediction holds none of it and the inliers measure nothing; the correlation
    filter's window still sees it, and the superpixels searched again around its peak find it there.
    Without the setting the frame has no measurement."""
    found = {recentre: _centre_found_after_a_jump({"fusion.recentre": recentre}, TRACKING) for recentre in (0.5, None)}
    assert found[0.5] is not None and np.allclose(found[0.5], (80, 60), atol=2.0)
    assert found[None] is None


def test_presence_is_judged_at_the_prediction_even_after_a_search_around_the_filter_peak():
    """``fusion.present``: a frame the inliers do not measure is present when the correlation filter sees the
    target within half a box of the prediction.  When the target has jumped 1.25 boxes the filter's
    confident peak starts a second search there (``fusion.recentre``); if that finds nothing either, the
    frame is not present, although the search was centred on the peak."""
    still = _measured_after_a_jump({}, TRACKING, jump=0, blind=True)
    jumped = _measured_after_a_jump({}, TRACKING, jump=30, blind=True)
    c = recipe_config("mil").correlation
    confident_psr = c.psr_low + recipe_config("mil").fusion.present * (c.psr_high - c.psr_low)
    assert jumped.stages["psr"] >= confident_psr   # the filter does see the jumped target (a second search ran)
    assert still.box is None and still.present
    assert jumped.box is None and not jumped.present
