"""Kalman filter and IMM maths against closed-form cases."""

import numpy as np
import pytest

from vidtrack.filters.imm import IMMEstimator, imm_combine, imm_mix, uniform_transition_matrix
from vidtrack.filters.kalman import (KalmanFilter, axis_process_noise, axis_transition, kf_predict, kf_update,
                                     motion_model)


def test_scalar_update_matches_closed_form():
    # Prior N(0, 4), measurement 2 with variance 1: posterior mean 8/5, variance 4/5.
    res = kf_update(np.array([0.0]), np.array([[4.0]]), np.array([2.0]), np.eye(1), np.eye(1))
    assert res.x[0] == pytest.approx(1.6)
    assert res.P[0, 0] == pytest.approx(0.8)
    assert res.innovation[0] == pytest.approx(2.0)
    assert res.S[0, 0] == pytest.approx(5.0)
    assert res.log_likelihood == pytest.approx(-0.5 * (4 / 5 + np.log(5) + np.log(2 * np.pi)))


def test_joseph_form_equals_standard_form_for_optimal_gain():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(4, 4))
    P = A @ A.T + np.eye(4)
    H = rng.normal(size=(2, 4))
    R = np.diag([0.5, 2.0])
    res = kf_update(np.zeros(4), P, np.ones(2), H, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    assert np.allclose(res.P, (np.eye(4) - K @ H) @ P)
    assert np.allclose(res.P, res.P.T)


def test_predict_constant_velocity():
    F, Q, H = motion_model("cv", dt=2.0, q=0.0, n_axes=1)
    x, P = kf_predict(np.array([1.0, 3.0]), np.eye(2), F, Q)
    assert np.allclose(x, [7.0, 3.0])
    assert np.allclose(P, [[5.0, 2.0], [2.0, 1.0]])
    assert np.allclose(H, [[1.0, 0.0]])


def test_motion_models_embed_in_higher_order():
    assert np.allclose(axis_transition("dr", 1.0, order=3), np.diag([1.0, 0.0, 0.0]))
    assert np.allclose(axis_transition("ca", 0.5), [[1, 0.5, 0.125], [0, 1, 0.5], [0, 0, 1]])
    Q = axis_process_noise("cv", 1.0, q=2.0)
    assert np.allclose(Q, 2.0 * np.array([[0.25, 0.5], [0.5, 1.0]]))
    F, Q, H = motion_model("ca", n_axes=2)
    assert F.shape == Q.shape == (6, 6) and H.shape == (2, 6)
    assert H[1, 3] == 1.0


def test_kalman_converges_to_constant_velocity_track():
    F, Q, H = motion_model("cv", q=1e-4, n_axes=1)
    kf = KalmanFilter(F, Q, H, np.eye(1) * 4.0)
    kf.initialize(np.zeros(2), np.eye(2) * 100.0)
    rng = np.random.default_rng(0)
    for k in range(200):
        kf.predict()
        kf.update(np.array([3.0 * k + rng.normal(0, 2.0)]))
    assert kf.x_[1] == pytest.approx(3.0, abs=0.05)


def test_imm_with_identical_models_equals_kalman():
    F, Q, H = motion_model("cv", q=0.1, n_axes=1)
    R = np.eye(1)
    kf = KalmanFilter(F, Q, H, R)
    imm = IMMEstimator([KalmanFilter(F, Q, H, R), KalmanFilter(F, Q, H, R)], uniform_transition_matrix(2))
    kf.initialize(np.zeros(2), np.eye(2))
    imm.initialize(np.zeros(2), np.eye(2))
    for z in [1.0, 2.5, 2.9, 4.2]:
        kf.predict()
        kf.update(np.array([z]))
        imm.predict()
        imm.update(np.array([z]))
    assert np.allclose(imm.x_, kf.x_) and np.allclose(imm.P_, kf.P_)
    assert np.allclose(imm.mu_, [0.5, 0.5])


def test_imm_mixing_and_combination_moments():
    xs = np.array([[0.0], [2.0]])
    Ps = np.array([[[1.0]], [[1.0]]])
    x, P = imm_combine(xs, Ps, np.array([0.5, 0.5]))
    assert x[0] == pytest.approx(1.0) and P[0, 0] == pytest.approx(2.0)  # 1 + spread of means
    x0, P0, c = imm_mix(xs, Ps, np.array([0.25, 0.75]), np.eye(2))
    assert np.allclose(x0, xs) and np.allclose(c, [0.25, 0.75])


def test_imm_prefers_the_right_model():
    # Target moving at constant velocity: the CV model should dominate the DR model.
    order = 2
    F_dr, Q_dr, H = motion_model("dr", q=1.0, n_axes=1, order=order)
    F_cv, Q_cv, _ = motion_model("cv", q=1e-3, n_axes=1)
    imm = IMMEstimator([KalmanFilter(F_dr, Q_dr, H, np.eye(1)), KalmanFilter(F_cv, Q_cv, H, np.eye(1))],
                       np.array([[0.95, 0.05], [0.05, 0.95]]))
    imm.initialize(np.zeros(2), np.eye(2) * 10)
    for k in range(50):
        imm.predict()
        imm.update(np.array([2.0 * k]))
    assert imm.mu_[1] > 0.9
