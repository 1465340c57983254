"""Support Vector Kalman: normalisation maths, Q floor, filter and experiment."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from vidtrack.filters.kalman import KalmanFilter, axis_transition, measured_axis_model
from vidtrack.filters.svk import SupportVectorKalman, learned_process_noise, svk_predict
from vidtrack.learn.svr import learn_row, learn_transition, process_noise_floor, window_scaling


def test_window_scaling_is_the_two_step_normalisation():
    X = np.array([[1.0, 10.0], [3.0, 30.0], [2.0, 14.0]])
    y = np.array([5.0, -5.0, 1.0])
    s = window_scaling(X, y)
    np.testing.assert_allclose(s.center_in, [2.0, 20.0])  # eq. 11: mid-range
    np.testing.assert_allclose(s.half_range_in, [1.0, 10.0])
    Xt, yt = s.inputs(X), s.outputs(y)
    np.testing.assert_allclose(Xt.min(0), -1.0)  # eq. 12: [-1, 1]
    np.testing.assert_allclose(Xt.max(0), 1.0)
    np.testing.assert_allclose([yt.min(), yt.max()], [-1.0, 1.0])


def test_unnormalised_row_reproduces_the_normalised_model_exactly():
    # eq. 13: any normalised weights map back to a row giving the same predictions.
    rng = np.random.default_rng(1)
    X, y = rng.normal(size=(10, 3)) * [1.0, 50.0, 0.01] + [5.0, -100.0, 2.0], rng.normal(size=10) * 7.0
    s = window_scaling(X, y)
    w = np.array([0.3, -0.7, 1.2])
    row = s.unnormalised_row(w)
    normalised = s.center_out + s.half_range_out * (s.inputs(X) @ w)
    np.testing.assert_allclose(s.center_out + (X - s.center_in) @ row, normalised, rtol=1e-12)


@pytest.mark.parametrize("a", [0.9, 1.0, 1.05, -0.5])
def test_known_scalar_linear_system_is_recovered_exactly(a):
    x = 7.0 * a ** np.arange(11)  # x_k = a x_{k-1}
    X, y = x[:-1, None], x[1:]
    row = learn_row(X, y, C=1e4, epsilon=0.0)
    if np.ptp(X) > 0:
        assert row.row[0] == pytest.approx(a, rel=1e-4)
    # The prediction of the next state is exact either way (centre translation included).
    assert row.offset + row.row @ [x[-1]] == pytest.approx(a * x[-1], rel=1e-4, abs=1e-8)


def test_known_diagonal_system_recovers_its_transition_matrix():
    A = np.diag([0.95, 1.1])
    xs = [np.array([4.0, -2.0])]
    for _ in range(10):
        xs.append(A @ xs[-1])
    xs = np.array(xs)
    F, u, var = learn_transition(xs[:-1], xs[1:], C=1e4, epsilon=0.0)
    np.testing.assert_allclose(F, A, atol=1e-4)
    np.testing.assert_allclose(F @ xs[-1] + u, A @ xs[-1], rtol=1e-4)
    assert np.all(var < 1e-6)


def test_constant_velocity_motion_is_predicted_through_the_offset():
    # A point at constant velocity: velocity is constant in the window, the
    # learned model must still predict p + v dt exactly.
    dt, v = 0.5, 3.0
    states = np.array([[2.0 + v * dt * k, v] for k in range(11)])
    F, u, var = learn_transition(states[:-1], states[1:], C=1e4, epsilon=0.0)
    np.testing.assert_allclose(F @ states[-1] + u, [states[-1, 0] + v * dt, v], rtol=1e-6)


def test_small_C_flattens_the_model():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(10, 2))
    y = X @ [0.8, 0.4]
    assert np.abs(learn_row(X, y, C=2.0 ** -10, epsilon=0.1).weights).max() < 0.02
    assert np.abs(learn_row(X, y, C=2.0, epsilon=0.0).weights).max() > 0.5


def test_cv_variance_is_the_mean_squared_residual_in_state_units():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(10, 1)) * 100.0
    y = 2.0 * X[:, 0] + rng.normal(size=10) * 5.0
    row = learn_row(X, y, C=10.0, epsilon=0.0)
    assert 5.0 < row.variance < 400.0  # residual std ~5 in state units, not normalised units


def test_q_floor_is_ten_percent_of_matching_R():
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    R = np.diag([100.0, 400.0])
    floor = process_noise_floor(H, R)
    np.testing.assert_allclose(floor, [10.0, 25.0, 40.0, 25.0])  # unmeasured: 10% of mean R
    np.testing.assert_allclose(process_noise_floor(np.eye(2), 1000 * np.eye(2)), [100.0, 100.0])
    Q = learned_process_noise([1e-6, 500.0, 3.0, 30.0], floor)
    np.testing.assert_allclose(np.diag(Q), [10.0, 500.0, 40.0, 30.0])
    assert np.count_nonzero(Q - np.diag(np.diag(Q))) == 0


def test_svk_q_never_falls_below_floor_and_keeps_listening():
    # A stationary point: the SVR residuals are tiny, yet Q stays at 10% of R.
    r = 100.0
    svk = SupportVectorKalman(np.eye(2), r * np.eye(2), axis_transition("cv", 0.5), np.eye(2), C=2.0 ** -10)
    svk.initialize(np.zeros(2), r * np.eye(2))
    rng = np.random.default_rng(0)
    for _ in range(60):
        svk.predict()
        svk.update(rng.normal(0, 10.0, size=2))
    assert svk.learned_
    assert np.all(np.diag(svk.Q_) >= 0.1 * r - 1e-9)
    svk.predict()
    before = svk.x_.copy()
    svk.update(np.array([50.0, 0.0]))
    assert svk.x_[0] - before[0] > 1.0  # the measurement still moves the estimate


def test_svk_bootstraps_with_the_default_model_then_learns():
    F0 = axis_transition("cv", 1.0)
    svk = SupportVectorKalman(np.eye(2), np.eye(2), F0, 0.01 * np.eye(2), window=10)
    svk.initialize(np.zeros(2), np.eye(2))
    for k in range(1, 10):
        svk.predict()
        svk.update(np.array([2.0 * k, 2.0]))
        assert not svk.learned_
        np.testing.assert_array_equal(svk.F_, F0)
    svk.predict()
    svk.update(np.array([20.0, 2.0]))
    assert svk.learned_
    assert set(svk.scalars_) == {"F_00", "F_01", "F_10", "F_11", "Q_00", "Q_11"}


def test_svk_predict_agrees_with_kalman_filter_when_offset_is_zero():
    F, Q, H, R = measured_axis_model("cv", dt=0.5, q=1.0, r=100.0)
    kf = KalmanFilter(F, Q, H, R)
    kf.initialize(np.array([1.0, 2.0]), np.eye(2))
    x, P = svk_predict(np.array([1.0, 2.0]), np.eye(2), F, Q, np.zeros(2))
    kx, kP = kf.predict()
    np.testing.assert_allclose(x, kx)
    np.testing.assert_allclose(P, kP)


def test_measured_axis_model_embeds_with_unmodelled_variance():
    F, Q, H, R = measured_axis_model("dr", dt=0.5, q=1.0, r=100.0, order=3, unmodelled_q=7.0)
    np.testing.assert_array_equal(F, np.diag([1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(np.diag(Q), [1.0, 7.0, 7.0])
    np.testing.assert_array_equal(H, [[1, 0, 0], [0, 1, 0]])
    F, Q, H, R = measured_axis_model("dr", dt=0.5, q=1.0, r=100.0)
    assert H.shape == (2, 1) and R.shape == (2, 2)


def test_svk_tables_one_run_matches_the_paper():
    from vidtrack.experiments import svk_tables

    parser = argparse.ArgumentParser()
    svk_tables.add_arguments(parser)
    args = parser.parse_args([])
    makers = svk_tables.make_filters(args, "linear", 100.0)
    assert set(makers) == set(svk_tables.FILTER_NAMES)
    chosen = {name: makers[name] for name in ("SVK", "Kalman DR Q=1e-2R")}
    errors = svk_tables.squared_errors(100.0, chosen, np.random.default_rng(0),
                                       svk_tables.linear_motion())
    svk_rmse = float(np.sqrt(errors["SVK"].mean()))
    assert abs(svk_rmse - 22.41) / 22.41 < 0.25  # Table 1, whole sequence
    assert np.sqrt(errors["Kalman DR Q=1e-2R"].mean()) > 1000.0
    mean_sq = {name: errors.get(name, errors["SVK"]) for name in svk_tables.FILTER_NAMES}
    rows = svk_tables.summarise("linear", mean_sq)
    assert set(rows[0]) == {"filter", "whole", "CA", "Drift", "CV", "CA*", "Drift*", "CV*"}
    table = svk_tables.format_table({"experiment": "svk-linear", "runs": 1, "seed": 0, "R100": rows})
    assert "Table 1" in table and "Kalman DR Q=1e-4R" in table


def test_average_rows_is_the_columnwise_mean_of_per_run_rmse():
    from vidtrack.experiments.svk_tables import average_rows

    runs = [[{"filter": "SVK", "whole": 10.0}], [{"filter": "SVK", "whole": 30.0}]]
    assert average_rows(runs) == [{"filter": "SVK", "whole": 20.0}]
