"""IMM: models of different order (MixedOrderIMM) against the embedded IMMEstimator, and the SVK-table variants."""

import argparse

import numpy as np

from vidtrack.experiments import svk_tables
from vidtrack.filters.imm import IMMEstimator, MixedOrderIMM, mixed_order_mix, uniform_transition_matrix
from vidtrack.filters.kalman import KalmanFilter, measured_axis_model


def _filters(order=None, unmodelled_q=0.0):
    return [KalmanFilter(*measured_axis_model(m, dt=0.5, q=1.0, r=100.0, order=order, unmodelled_q=unmodelled_q))
            for m in ("dr", "cv", "ca")]


def test_mixed_order_imm_with_equal_sizes_is_the_imm_estimator():
    rng = np.random.default_rng(0)
    M = np.array([[0.9, 0.05, 0.05], [0.1, 0.8, 0.1], [0.2, 0.2, 0.6]])
    a, b = IMMEstimator(_filters(3, 100.0), M), MixedOrderIMM(_filters(3, 100.0), M)
    x0, P0 = np.array([0.0, 10.0, 0.0]), 100.0 * np.eye(3)
    a.initialize(x0, P0)
    b.initialize(x0, P0)
    for k in range(40):
        z = np.array([5.0 * k + 0.1 * k * k, 5.0 + 0.2 * k]) + rng.normal(0, 10.0, 2)
        a.predict()
        b.predict()
        a.update(z)
        b.update(z)
        assert np.allclose(a.x_, b.x_) and np.allclose(a.P_, b.P_) and np.allclose(a.mu_, b.mu_)


def test_augmentation_with_zero_or_own_estimate():
    xs = [np.array([1.0]), np.array([1.0, 4.0]), np.array([1.0, 4.0, 2.0])]
    Ps = [np.eye(1), np.eye(2), np.eye(3)]
    mu = np.array([0.5, 0.25, 0.25])
    M = uniform_transition_matrix(3)
    x_zero, _, _ = mixed_order_mix(xs, Ps, mu, M, pad="zero")
    x_own, P_own, _ = mixed_order_mix(xs, Ps, mu, M, pad="own")
    # zero augmentation: DR's (absent) velocity counts as 0 and drags CA's mixed velocity and acceleration
    assert np.allclose(x_zero[2], [1.0, 0.5 * 4.0, 0.25 * 2.0])
    # own: DR's missing components are CA's own, so nothing is dragged
    assert np.allclose(x_own[2], [1.0, 4.0, 2.0]) and np.allclose(P_own[2], np.eye(3))
    assert [len(x) for x in x_own] == [1, 2, 3]


def test_svk_imm_variants_run_and_report_against_the_paper(monkeypatch):
    few = {k: svk_tables.IMM_VARIANTS[k] for k in list(svk_tables.IMM_VARIANTS)[:1]}
    few["native, augmented own estimate, mode"] = {"formulation": "native-own", "estimate": "mode"}
    monkeypatch.setattr(svk_tables, "IMM_VARIANTS", few)
    parser = argparse.ArgumentParser()
    svk_tables.add_arguments(parser)
    args = parser.parse_args([])
    args.seed, args.experiment = 0, "svk-nonlinear"
    out = svk_tables.imm_variants(args, "nonlinear", svk_tables.nonlinear_motion(), runs=1)
    assert set(out) == set(svk_tables.IMM_VARIANTS)
    for tables in out.values():
        assert set(tables) == {"R100", "R1000"}
        assert all(np.isfinite(v) and v > 0 for t in tables.values() for v in t.values())
    table = svk_tables.format_imm_variants({"experiment": "svk-nonlinear", "imm_variant_runs": 1, "imm_variants": out})
    assert "paper" in table and "289.90" in table


def test_float64_mode_probabilities_underflow_to_the_predicted_ones():
    from vidtrack.filters.imm import float_mode_probabilities as probs

    c = np.array([0.2, 0.3, 0.5])
    logL = np.array([-3.0, -1.0, -2.0])
    w = c * np.exp(logL)
    assert np.allclose(probs(c, logL), w / w.sum())  # no underflow: the exact posterior
    assert np.allclose(probs(c, logL, np.float32), w / w.sum(), rtol=1e-6)
    assert np.allclose(probs(c, np.array([-800.0, -1.0, -900.0])), [0, 1, 0])
    assert np.allclose(probs(c, np.array([-800.0, -760.0, -900.0])), c)  # all underflow: the predicted ones
    assert np.allclose(probs(c, np.array([-120.0, -110.0, -500.0]), np.float32), c)  # float32 underflows sooner
    assert np.allclose(probs(c, np.array([-120.0, -110.0, -500.0])), [0, 1, 0], atol=1e-4)
