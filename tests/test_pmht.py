"""PMHT (Streit & Luginbuhl) on the Kalman functions: smoother, E-step, M-step and the sliding batch."""

import numpy as np

from vidtrack.filters.kalman import KalmanFilter, motion_model
from vidtrack.filters.pmht import PMHT, assignment_weights, rts_smoother, synthetic_measurement


def _track(rng, T=60):
    F, Q, H = motion_model("cv", q=0.05, n_axes=2)
    x = np.array([50.0, 1.0, 40.0, -0.5])
    xs = []
    for _ in range(T):
        x = F @ x + rng.multivariate_normal(np.zeros(4), Q)
        xs.append(x)
    return F, Q, H, np.array(xs)


def test_rts_smoother_ends_at_the_kalman_filter_and_smooths_better():
    rng = np.random.default_rng(0)
    F, Q, H, xs = _track(rng)
    R = 4.0 * np.eye(2)
    zs = [H @ x + rng.normal(0, 2.0, 2) for x in xs]
    x0, P0 = xs[0], 10.0 * np.eye(4)
    kf = KalmanFilter(F, Q, H, R)
    kf.initialize(x0, P0)
    filtered = []
    for z in zs:
        kf.predict()
        kf.update(z)
        filtered.append(kf.x_.copy())
    smoothed, Ps = rts_smoother(x0, P0, F, Q, H, zs, [R] * len(zs))
    assert np.allclose(smoothed[-1], filtered[-1])  # the last frame: smoothing = filtering

    def err(est):
        return np.sqrt(np.mean(np.sum((est @ H.T - xs @ H.T) ** 2, axis=1)))

    assert err(smoothed) < err(np.array(filtered))
    assert np.all(np.linalg.eigvalsh(Ps[0]) > 0)


def test_assignment_weights_split_targets_and_clutter():
    means = np.array([[0.0, 0.0], [100.0, 0.0]])
    dets = np.array([[0.5, 0.0], [99.0, 1.0], [50.0, 50.0]])
    w = assignment_weights(dets, means, np.eye(2), np.array([0.4, 0.4]), clutter_weight=0.2 / 1e4)
    assert w[0, 0] > 0.99 and w[1, 1] > 0.99
    assert w[2].sum() < 1e-6  # far from both targets: clutter
    assert np.all(w.sum(axis=1) <= 1.0 + 1e-12)


def test_synthetic_measurement_is_the_weighted_mean_with_scaled_covariance():
    z, R = synthetic_measurement(np.array([[0.0, 0.0], [2.0, 4.0]]), np.array([0.25, 0.25]), np.eye(2))
    assert np.allclose(z, [1.0, 2.0]) and np.allclose(R, 2.0 * np.eye(2))
    assert synthetic_measurement(np.zeros((0, 2)), np.zeros(0), np.eye(2)) == (None, None)


def test_pmht_without_clutter_and_window_one_is_the_kalman_filter():
    rng = np.random.default_rng(1)
    F, Q, H, xs = _track(rng, T=30)
    R = 4.0 * np.eye(2)
    zs = [H @ x + rng.normal(0, 2.0, 2) for x in xs]
    pmht = PMHT(F, Q, H, R, clutter_density=1e-12, p_detect=1.0, area=1e4, window=1, iterations=3)
    kf = KalmanFilter(F, Q, H, R)
    x0, P0 = xs[0], 10.0 * np.eye(4)
    pmht.initialize(x0[None], P0[None])
    kf.initialize(x0, P0)
    for z in zs:
        kf.predict()
        kf.update(z)
        got = pmht.step(z[None])
        assert np.allclose(got[0], kf.x_, atol=1e-6)


def test_pmht_follows_two_targets_through_clutter():
    rng = np.random.default_rng(2)
    F, Q, H, a = _track(rng, T=80)
    _, _, _, b = _track(rng, T=80)
    b = b + np.array([150.0, 0, 100.0, 0])
    R = 4.0 * np.eye(2)
    pmht = PMHT(F, Q, H, R, clutter_density=2.0 / (320 * 240), p_detect=0.9, area=320 * 240, window=5, iterations=4)
    pmht.initialize(np.array([a[0], b[0]]), np.array([10.0 * np.eye(4)] * 2))
    errors = []
    for k in range(1, 80):
        dets = [H @ t[k] + rng.normal(0, 2.0, 2) for t in (a, b) if rng.random() < 0.9]
        dets += list(rng.uniform([0, 0], [320, 240], size=(rng.poisson(2.0), 2)))
        est = pmht.step(np.array(dets).reshape(-1, 2)) @ H.T
        errors.append([np.linalg.norm(est[0] - H @ a[k]), np.linalg.norm(est[1] - H @ b[k])])
    assert np.sqrt(np.mean(np.square(errors))) < 4.0
