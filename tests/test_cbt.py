"""Channel-Based Tracking: learning (eq. 11, Baum-Welch, correspondence-free), EKF/PDAF comparators,
the two reproductions (small), the video filter (its grid bounded by the box), `vidtrack learn cbt` and
`--model` errors."""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import pytest

from vidtrack.errors import UsageError
from vidtrack.channels import (ChannelBasis, decode, decode_modes, embedded_predict, encode, position_conditional,
                               random_walk_displacement, shift_tensor)
from vidtrack.filters.cbt import CBTFilter, grid_megabytes
from vidtrack.filters.cbt_model import CBTModel
from vidtrack.filters.channels import ChannelBayesFilter
from vidtrack.filters.ekf import ExtendedKalmanFilter
from vidtrack.filters.kalman import KalmanFilter, motion_model
from vidtrack.filters.pdaf import pdaf_update
from vidtrack.learn.baum_welch import (baum_welch, chain_counts, covariance_transition, embed_history,
                                       embedded_covariance, likelihoods, measurement_matrix)
from vidtrack.measure.detections import DetectionMeasurer, score_map_peaks
from vidtrack.recipes import build_tracker
from vidtrack.types import Detections

from conftest import synthetic_sequence

BASIS = ChannelBasis(0.0, 30.0, 20)


def test_covariance_estimate_eq11_learns_a_deterministic_drift():
    x = np.arange(0.0, 30.0, 1.0)  # x_k = x_{k-1} + 1
    c = encode(x, BASIS)
    F = covariance_transition(c[1:], c[:-1])
    visited = c[:-1].sum(axis=0) > 0.5
    assert np.allclose(F.sum(axis=0)[visited], 1.0)  # conditional: columns normalised by the marginal
    predicted = F @ encode(10.0, BASIS)
    assert BASIS.from_channel(decode(predicted)[0]) == pytest.approx(11.0, abs=0.3)


def test_second_order_embedding_learns_what_first_order_cannot():
    rng = np.random.default_rng(0)
    seqs = []
    for _ in range(60):  # constant velocity +-2 per step (about a channel), random start and direction
        v = rng.choice([-2.0, 2.0])
        x0 = rng.uniform(3, 27)
        seqs.append(encode(np.clip(x0 + v * np.arange(8), 0, 30), BASIS))
    G2 = embedded_covariance(seqs, order=2)
    W = embed_history(encode([13.0, 15.0], BASIS), 2, 1)  # x_k = 15.0 after 13.0: moving up
    up = decode(embedded_predict(W, G2).sum(axis=1))[0]
    W = embed_history(encode([17.0, 15.0], BASIS), 2, 1)  # moving down
    down = decode(embedded_predict(W, G2).sum(axis=1))[0]
    assert BASIS.from_channel(up) == pytest.approx(17.0, abs=0.6)
    assert BASIS.from_channel(down) == pytest.approx(13.0, abs=0.6)
    G1 = embedded_covariance(seqs, order=1)  # first order: both directions, a bimodal prediction
    modes = decode_modes(embedded_predict(encode(15.0, BASIS), G1), threshold=0.2)
    found = sorted(float(BASIS.from_channel(t)) for t, _ in modes)
    assert len(found) == 2 and found == pytest.approx([13.0, 17.0], abs=1.0)


def test_measurement_matrix_maps_state_to_measurement_channels():
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 30, 2000)
    z_basis = ChannelBasis(0, 45, 12)
    H = measurement_matrix(encode(1.5 * x, z_basis), encode(x, BASIS))  # z = 1.5 x
    assert H.shape == (12, 20) and np.allclose(H.sum(axis=0), 1.0)
    h = likelihoods(H, encode([30.0], z_basis))[0]  # h(z) = H' c(z): most likely x = 20
    assert BASIS.from_channel(decode(h)[0]) == pytest.approx(20.0, abs=1.0)


def _hmm_data(rng, T=120, n=5):
    seqs, truth = [], []
    for _ in range(n):
        x = np.empty(T)
        x[0] = rng.uniform(5, 25)
        for k in range(1, T):
            x[k] = np.clip(x[k - 1] + 0.6 + rng.normal(0, 0.5), 0, 30)
            if x[k] >= 29.5:
                x[k] = 1.0
        truth.append(x)
        seqs.append(encode(np.clip(x + rng.normal(0, 0.7, T), 0, 30), BASIS))
    return seqs, truth


def test_baum_welch_increases_the_likelihood_and_converges():
    rng = np.random.default_rng(2)
    z, truth = _hmm_data(rng)
    G0 = np.full((20, 20), 1.0 / 20)  # uninformative start
    G0 = embedded_covariance(z, order=1) * 0.5 + G0 * 0.5
    H0 = np.eye(20) * 0.8 + 0.2 / 20
    res = baum_welch(z, G0, H0, iterations=6, tol=0.0)
    ll = res.log_likelihood
    assert len(ll) == 6
    assert all(b >= a - 1e-6 for a, b in zip(ll, ll[1:]))  # EM never decreases the likelihood
    assert res.change[-1] < res.change[0]
    assert np.allclose(res.G.sum(axis=0), 1.0) and np.allclose(res.H.sum(axis=0), 1.0)
    # the refined model predicts the drift
    predicted = res.G @ encode(12.0, BASIS)
    assert 12.0 < BASIS.from_channel(decode(predicted)[0]) < 13.5
    sqrt_res = baum_welch(z, G0, H0, iterations=2, product="sqrt")
    assert np.all(np.isfinite(sqrt_res.G))


def test_correspondence_free_learning_from_unassociated_detections():
    rng = np.random.default_rng(3)
    bases = (ChannelBasis(0, 100, 20), ChannelBasis(0, 100, 20))
    sets = []
    a, b = np.array([20.0, 50.0]), np.array([80.0, 50.0])
    for k in range(200):  # two objects moving right at 1.5 px/frame (wrapping), clutter, drop-outs
        a = np.array([(20.0 + 1.5 * k) % 90 + 5, 30.0])
        b = np.array([(60.0 + 1.5 * k) % 90 + 5, 70.0])
        pts = [p + rng.normal(0, 0.7, 2) for p in (a, b) if rng.random() < 0.85]
        pts += list(rng.uniform(0, 100, (rng.poisson(2), 2)))
        sets.append(np.array(pts).reshape(-1, 2)[rng.permutation(len(pts))])
    counts = chain_counts(sets, bases, order=2, gate=6.0)
    G = (counts[0] + 1e-6) / (counts[0] + 1e-6).sum(axis=0, keepdims=True)
    W = embed_history(encode([48.5, 50.0], bases[0]), 2, 1)
    assert bases[0].from_channel(decode(embedded_predict(W, G).sum(axis=1))[0]) == pytest.approx(51.5, abs=1.0)


def test_channel_bayes_filter_tracks_carlin_like_sign_ambiguity_free_data():
    rng = np.random.default_rng(4)
    _, truth = _hmm_data(rng, n=1)
    x = truth[0]
    G = embedded_covariance([encode(x, BASIS)], order=1)
    H = measurement_matrix(encode(x, BASIS), encode(x, BASIS))
    f = ChannelBayesFilter(G, H)
    f.initialize(encode(x[0], BASIS))
    errors = []
    for k in range(1, len(x)):
        f.predict()
        f.update(f.likelihood(encode(x[k] + rng.normal(0, 0.7), BASIS)))
        errors.append(BASIS.from_channel(decode(f.marginal())[0]) - x[k])
    assert np.sqrt(np.mean(np.square(errors))) < 1.2


def test_ekf_on_a_linear_model_equals_the_kalman_filter():
    F, Q, H = motion_model("cv", q=0.5, n_axes=1)
    R = np.array([[2.0]])
    kf = KalmanFilter(F, Q, H, R)
    ekf = ExtendedKalmanFilter(lambda x: F @ x, lambda x: F, lambda x: H @ x, lambda x: H, Q, R)
    kf.initialize(np.array([1.0, 0.5]), np.eye(2))
    ekf.initialize(np.array([1.0, 0.5]), np.eye(2))
    for z in (1.7, 2.1, 3.5, 3.9):
        kf.predict()
        ekf.predict()
        kf.update(np.array([z]))
        ekf.update(np.array([z]))
    assert np.allclose(kf.x_, ekf.x_) and np.allclose(kf.P_, ekf.P_)


def test_pdaf_update():
    F, Q, H = motion_model("cv", q=1.0, n_axes=2)
    R = np.eye(2)
    x, P = np.array([10.0, 1.0, 20.0, 0.0]), np.eye(4) * 4
    nothing = pdaf_update(x, P, np.zeros((0, 2)), H, R)
    assert np.allclose(nothing.x, x) and nothing.beta0 == 1.0
    far = pdaf_update(x, P, np.array([[90.0, 90.0]]), H, R)  # outside the gate
    assert far.gated == 0 and np.allclose(far.x, x)
    one = pdaf_update(x, P, np.array([[12.0, 21.0]]), H, R, p_detect=0.99, clutter_density=1e-9)
    from vidtrack.filters.kalman import kf_update

    exact = kf_update(x, P, np.array([12.0, 21.0]), H, R)
    assert one.beta0 < 1e-3 and np.allclose(one.x, exact.x, atol=1e-3)
    two = pdaf_update(x, P, np.array([[12.0, 21.0], [8.0, 19.0]]), H, R)  # symmetric pair: pulls little
    assert abs(two.x[0] - x[0]) < abs(one.x[0] - x[0])


def test_score_map_peaks_with_non_maximum_suppression():
    scores = np.zeros((40, 60))
    scores[10, 10] = 0.9
    scores[11, 12] = 0.8  # suppressed by the stronger neighbour
    scores[30, 50] = 0.5
    scores[5, 55] = 0.1  # below min_score
    peaks = score_map_peaks(scores, radius=3, min_score=0.2)
    assert peaks.tolist() == [[10, 10, 0.9], [30, 50, 0.5]]
    assert len(score_map_peaks(scores, radius=3, min_score=0.2, max_peaks=1)) == 1


def test_cbt_tracks_a_synthetic_target_from_detections(moving_target):
    frames, boxes = moving_target
    tracker = build_tracker("cbt", seed=0)
    tracker.initialize(frames[0], boxes[0])
    for frame in frames[1:]:
        state = tracker.step(frame)
        assert 0.0 <= state.confidence <= 1.0
        det = state.stages["detections"]
        assert det.ndim == 2 and det.shape[1] == 3
        assert "score_map" in state.stages
    assert np.linalg.norm(state.box.center - boxes[-1].center) < 4.0
    assert state.status == "tracking" and state.confidence > 0.5
    assert np.any(tracker.filter.inner.counts_[0] > 0)  # learned online from its own estimates (inside MeasuredSizeFilter)


def test_cbt_configuration_reaches_the_measurer_and_the_filter():
    default = build_tracker("cbt", seed=0)
    assert default.filter.inner == CBTFilter()  # the recipe's defaults are the filter's
    assert default.measurer.inner == DetectionMeasurer()   # inside the appearance verification
    tracker = build_tracker("cbt", settings={"detections.min_score": "0.55", "order": "3", "product": "sqrt",
                                             "detector": "ncc", "detections.margin": "1.5"}, relearn_every=4)
    inner = tracker.filter.inner
    assert (inner.order, inner.product, inner.relearn_every) == (3, "sqrt", 4)
    assert tracker.measurer.inner == DetectionMeasurer(detector="ncc", margin=1.5, min_score=0.55)
    with pytest.raises(UsageError, match="cf, ncc"):
        build_tracker("cbt", detector="face")
    with pytest.raises(UsageError, match="detections.min_score"):
        build_tracker("cbt", settings={"min_score": "0.5"})  # a detections field, not a top-level one


def test_cbt_takes_the_order_of_its_model_file_unless_told(tmp_path, moving_target):
    frames, boxes = moving_target
    basis = ChannelBasis(-0.6, 0.6, 15)
    path = tmp_path / "order3.npz"
    D = random_walk_displacement(basis, 0.12, 3)
    CBTModel(basis, D, D).save(path)
    tracker = build_tracker("cbt", model=str(path))
    assert tracker.filter.inner.order == 3 and tracker.filter.inner.model.order == 3
    tracker.initialize(frames[0], boxes[0])
    assert tracker.filter.inner.G_[0].shape == (tracker.filter.inner.bases_[0].n,) * 4
    contradicting = build_tracker("cbt", model=str(path), order=2)
    with pytest.raises(UsageError, match="order 3"):
        contradicting.initialize(frames[0], boxes[0])


def test_cbt_filter_without_detections_is_lost_and_coasts(moving_target):
    frames, boxes = moving_target
    f = CBTFilter()
    f.initialize(boxes[0], frames[0])
    f.predict()
    est = f.update(Detections(np.zeros((0, 2)), np.zeros(0)))
    assert est.status == "lost" and est.scalars["raw_confidence"] == 0.0 and est.scalars["unmeasured"] == 1.0
    assert np.linalg.norm(est.box.center - boxes[0].center) < 3.0


def _write_otb_sequence(folder: Path, frames, boxes) -> None:
    (folder / "img").mkdir(parents=True)
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / "img" / f"{i + 1:04d}.png"), frame.image)
    (folder / "groundtruth_rect.txt").write_text(
        "\n".join(f"{b.x + 1},{b.y + 1},{b.w},{b.h}" for b in boxes) + "\n")


def test_learn_cli_writes_a_model_the_recipe_loads(tmp_path, capsys):
    from vidtrack.cli import main

    frames, boxes = synthetic_sequence(n=20, velocity=(2.0, 0.5), seed=5)
    _write_otb_sequence(tmp_path / "data" / "Synth", frames, boxes)
    out = tmp_path / "model.npz"
    assert main(["learn", "cbt", str(tmp_path / "data"), "--out", str(out)]) == 0
    model = CBTModel.load(out)
    assert model.order == 2 and model.Dx.shape == (model.basis.n,) * 2
    # the learned x model expects the motion: d = 2 px / sqrt(24 * 28) box sizes
    d = 2.0 / np.sqrt(24 * 28)
    assert model.basis.from_channel(decode(model.Dx @ encode(d, model.basis))[0]) == pytest.approx(d, abs=0.02)
    tracker = build_tracker("cbt", model=str(out))
    tracker.initialize(frames[0], boxes[0])
    for frame in frames[1:]:
        state = tracker.step(frame)
    assert np.linalg.norm(state.box.center - boxes[-1].center) < 4.0
    # from a video with --init-box
    out2 = tmp_path / "online.npz"
    b = boxes[0]
    assert main(["learn", "cbt", str(tmp_path / "data" / "Synth" / "img"), "--init-box",
                 f"{b.x},{b.y},{b.w},{b.h}", "--out", str(out2)]) == 0
    assert CBTModel.load(out2).order == 2
    # --prior-weight reaches the online learner too: a much heavier prior gives a different model
    out3 = tmp_path / "online_heavy_prior.npz"
    assert main(["learn", "cbt", str(tmp_path / "data" / "Synth" / "img"), "--init-box",
                 f"{b.x},{b.y},{b.w},{b.h}", "--out", str(out3), "--prior-weight", "10000"]) == 0
    assert not np.allclose(CBTModel.load(out3).Dx, CBTModel.load(out2).Dx)


@pytest.mark.parametrize("content", [None, b"not a zip", "other-npz"])
def test_missing_or_malformed_model_is_a_one_line_usage_error(tmp_path, capsys, content):
    from vidtrack.cli import main

    path = tmp_path / "model.npz"
    if content == "other-npz":
        np.savez(path, a=np.arange(3))
    elif content is not None:
        path.write_bytes(content)
    with pytest.raises(UsageError):
        build_tracker("cbt", model=str(path))
    frames, boxes = synthetic_sequence(n=3)
    video = tmp_path / "frames"
    video.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(video / f"{i:04d}.png"), f.image)
    b = boxes[0]
    assert main([str(video), "--init-box", f"{b.x},{b.y},{b.w},{b.h}", "--filter", "cbt", "--model", str(path), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vidtrack: error: --model") and "\n" not in err


def test_carlin_reproduction_small():
    from vidtrack.experiments import cbt_carlin

    args = argparse.Namespace(runs=8, seed=0, steps=50, train=30, channels=12, order=2, baum_welch=2,
                              bw_product="plain", bw_prior=10.0, bw_learn_h=False)
    result = cbt_carlin.run(args, lambda it, **kw: it)
    rmse = result["rmse"]
    assert set(rmse) == {"CBT", "EKF", "Grid", "SIR PF"} and result["runs"] == 8
    assert rmse["CBT"] < 7.0 and rmse["SIR PF"] < 7.0 and rmse["EKF"] > 10.0
    ll = result["baum_welch"]["log_likelihood"]
    assert len(ll) == 2 and ll[1] >= ll[0] and np.isfinite(result["rmse_extra"]["CBT+BW"])
    assert "Channel Based Tracking" in cbt_carlin.format_table(result)
    # the paper's values beside vidtrack's, and the claims, in the JSON
    cbt = next(c for c in result["vs_paper"] if c["row"] == "CBT")
    assert cbt["paper"] == 5.43 and cbt["rel_diff"] == pytest.approx((rmse["CBT"] - 5.43) / 5.43)
    assert [c["holds"] for c in result["claims"]] and all(isinstance(c["holds"], bool) for c in result["claims"])


def test_detections_reproduction_small():
    from vidtrack.experiments import cbt_detections

    args = argparse.Namespace(runs=1, seed=0, frames=150, objects=2, clutter=3.0, channels=20, order=2, iterations=0,
                              bw_product="sqrt", bw_prior=0.1, no_pmht=False)
    result = cbt_detections.run(args, lambda it, **kw: it)
    r = result["rmse"]
    assert set(r) == {"CBT", "CBT associated", "PMHT", "PDAF", "Detector"} and set(r["CBT"]) == {"inf", "20", "5"}
    assert r["CBT"]["inf"] < r["Detector"]["inf"]
    assert r["CBT"]["5"] <= r["CBT"]["20"] <= r["CBT"]["inf"]
    assert "Detector" in cbt_detections.format_table(result)


def test_shift_tensor_moves_every_axis_and_drops_what_leaves():
    W = np.zeros((6, 6))
    W[3, 2] = 1.0
    W[0, 0] = 0.5
    moved = shift_tensor(W, 2)   # the grid's origin moved up 2 channels
    assert moved[1, 0] == 1.0 and moved.sum() == 1.0   # the mass at channel 0 left the grid
    assert shift_tensor(moved, -2)[3, 2] == 1.0
    assert shift_tensor(W, 0) is W and not shift_tensor(W, 6).any()


def test_position_conditional_is_translation_invariant_on_any_window():
    d_basis = ChannelBasis(-0.6, 0.6, 15)
    D = random_walk_displacement(d_basis, 0.12, 2)
    at_origin = position_conditional(D, d_basis, ChannelBasis(0.0, 40.0, 23), 10.0)
    elsewhere = position_conditional(D, d_basis, ChannelBasis(600.0, 640.0, 23), 10.0)
    np.testing.assert_array_equal(at_origin, elsewhere)   # moving the window by whole channels keeps G


def test_cbt_grid_follows_a_small_box_across_a_large_frame():
    # a 10x10 box on 1280x720 (frame/box ratio 128): the grid is a window of the box, not the frame,
    # and it follows the target over 3 window widths
    frames, boxes = synthetic_sequence(n=120, size=(1280, 720), box=(100, 300, 10, 10), velocity=(2.5, 0.5))
    tracker = build_tracker("cbt", seed=0)
    tracker.initialize(frames[0], boxes[0])
    inner = tracker.filter.inner
    assert [b.n for b in inner.bases_] == [53, 53]   # 100 px window / 2 px spacing + 3
    assert all(G.nbytes < 2 ** 21 for G in inner.G_)
    errors = [np.linalg.norm(tracker.step(frame).box.center - box.center) for frame, box in zip(frames[1:], boxes[1:])]
    assert max(errors) < 7.5   # never more than three quarters of the box off
    assert inner.bases_[0].lo > 300.0   # the window moved with the target


def test_cbt_grid_covers_a_frame_smaller_than_its_window_as_a_whole():
    frames, boxes = synthetic_sequence(n=3, size=(160, 120), box=(20, 40, 24, 28))
    f = CBTFilter()
    f.initialize(boxes[0], frames[0])
    whole = [ChannelBasis.with_spacing(0.0, 160.0, f.spacing_), ChannelBasis.with_spacing(0.0, 120.0, f.spacing_)]
    assert list(f.bases_) == whole and f.origin_ == [0, 0]


def test_cbt_over_its_memory_budget_is_refused_before_tracking(moving_target):
    frames, boxes = moving_target
    f = CBTFilter(spacing_boxes=0.01, min_spacing=0.1, window_boxes=40.0, order=3)
    with pytest.raises(UsageError, match=r"needs \d+ MB, over the 512 MB budget"):
        f.initialize(boxes[0], frames[0])
    assert grid_megabytes(53, 2) < 5.0   # the default grid of any box: 53 channels, order 2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cbt_follows_a_target_moving_a_third_of_its_size_a_frame(seed):
    """8 px a frame on a 24x28 box: within the default motion model's range (one box size a frame, a random walk
    of 0.2 box sizes to start from); a model reaching 0.6 box sizes with a 0.12 walk loses the target."""
    frames, boxes = synthetic_sequence(n=30, size=(480, 120), box=(20, 40, 24, 28), velocity=(8, 0.5), seed=seed)

    def final_error(settings):
        tracker = build_tracker("cbt", seed=0, settings=settings)
        tracker.initialize(frames[0], boxes[0])
        for frame in frames[1:]:
            state = tracker.step(frame)
        return np.linalg.norm(state.box.center - boxes[-1].center)

    assert final_error({}) < 4.0
    assert final_error({"d_range": 0.6, "prior_sigma": 0.12}) > 24.0
