"""IMM: models of different order (MixedOrderIMM) against the embedded IMMEstimator, and the SVK-table variants."""

import argparse

import numpy as np

from vidtrack.experiments import svk_imm, svk_tables
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


def _interval_rmse(est, truth):
    e2 = (est - truth) ** 2
    n = svk_tables.SEGMENT
    return [float(np.sqrt(e2[i * n:(i + 1) * n].mean())) for i in range(3)], [
        float(np.sqrt(e2[(i + 1) * n - svk_tables.STEADY:(i + 1) * n].mean())) for i in range(3)]


def test_q_readings_of_the_imm_models():
    dt, q, r = 0.5, 1e-2, 1.0
    common = svk_imm.imm(("dr", "cv", "ca"), dt=dt, q=q, r=r, unmodelled_q="q")
    assert all(np.allclose(f.Q, q * np.eye(3)) for f in common.filters)  # Q = q I on the common state
    white = svk_imm.imm(("dr", "cv", "ca"), dt=dt, q=q, r=r, unmodelled_q=1.0, q_form="white-noise")
    from vidtrack.filters.kalman import axis_process_noise

    expected = axis_process_noise("cv", dt, q, 3)
    expected[2, 2] = r  # CV's unmodelled acceleration
    assert np.allclose(white.filters[1].Q, expected)


def test_a_drift_model_without_the_velocity_makes_the_imm_cv_its_kalman_dr():
    # Its 1-D density beats the CV model's 2-D one at every sample: mu_DR -> 1 and the IMM is the Kalman DR.
    p, v = svk_tables.nonlinear_motion()
    r = 100.0
    z = np.stack([p, v], axis=1) + np.random.default_rng(3).normal(0.0, 10.0, size=(len(p), 2))
    filt = svk_imm.imm(("dr", "cv"), dt=0.01, q=1e-2 * r, r=r, unmodelled_q=1.0, formulation="native-zero",
                          pad_var=1.0, dr_velocity=False)
    est = svk_tables.run_filter(filt, z, r)
    dr = svk_tables.run_filter(svk_tables.kalman("dr", dt=0.01, q=1e-2 * r, r=r), z, r)
    assert filt.filters[0].update(z[5]).innovation.shape == (1,)
    rmse_imm, rmse_dr = np.sqrt(np.mean((est - p) ** 2)), np.sqrt(np.mean((dr - p) ** 2))
    assert abs(rmse_imm - rmse_dr) < 0.01 * rmse_dr
    assert filt.mu_[0] > 0.99


def test_padding_variance_trades_the_ca_interval_against_the_velocity_jump():
    # svk_tables docstring: a small variance of the missing derivatives loses the CA interval at R = 1000
    # (CV keeps weight and drags CA's acceleration) and follows the jump to the CV interval slowly;
    # a large one keeps the acceleration and follows the jump within a few samples, but is noisier at rest.
    p, v = svk_tables.linear_motion()
    rng = np.random.default_rng(0)
    out = {}
    for r in (100.0, 1000.0):
        z = np.stack([p, v], axis=1) + rng.normal(0.0, np.sqrt(r), size=(len(p), 2))
        for var in (0.01, 1.0):
            filt = svk_imm.imm(("dr", "cv", "ca"), dt=0.5, q=1e-4 * r, r=r, unmodelled_q=1.0,
                                  formulation="native-zero", pad_var=var)
            out[r, var] = _interval_rmse(svk_tables.run_filter(filt, z, r), p)
    (ca_small, _, cv_small), _ = out[1000.0, 0.01]
    (ca_large, _, cv_large), _ = out[1000.0, 1.0]
    assert ca_small > 1.5 * ca_large and cv_small > 3 * cv_large
    assert out[100.0, 0.01][1][1] < out[100.0, 1.0][1][1]  # the drift interval's last 80 samples


def test_carried_derivatives_and_underflow_leave_the_imm_cv_at_its_uniform_prior():
    # svk_tables docstring, Table 3: DR embedded with identity rows (velocity carried, unused) and float64
    # densities: on the sinusoids every density underflows, the mode probabilities stay at the uniform
    # prior and the IMM CV lags more than its Kalman DR; with log-likelihoods the same IMM is below it.
    p, v = svk_tables.nonlinear_motion()
    r = 100.0
    z = np.stack([p, v], axis=1) + np.random.default_rng(1).normal(0.0, 10.0, size=(len(p), 2))
    out = {}
    for likelihood in ("log", "float64"):
        filt = svk_imm.imm(("dr", "cv"), dt=0.01, q=1e-2 * r, r=r, unmodelled_q=0.0, carry=True,
                              likelihood=likelihood)
        assert np.array_equal(filt.filters[0].F, np.eye(2))
        filt.initialize(np.array(z[0]), r * np.eye(2))
        est, mu_dr = [z[0, 0]], []
        for k in range(1, len(z)):
            filt.predict()
            filt.update(z[k])
            est.append(filt.x_[0])
            mu_dr.append(filt.mu_[0])
        out[likelihood] = float(np.sqrt(np.mean((np.array(est) - p) ** 2))), float(np.mean(mu_dr[:svk_tables.SEGMENT - 1]))
    dr = svk_tables.run_filter(svk_tables.kalman("dr", dt=0.01, q=1e-2 * r, r=r), z, r)
    rmse_dr = float(np.sqrt(np.mean((dr - p) ** 2)))
    assert out["float64"][0] > 1.4 * rmse_dr and out["float64"][1] > 0.4
    assert out["log"][0] < rmse_dr and out["log"][1] < 0.05
