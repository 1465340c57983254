"""The 1-D simulation of the NormalHedge paper (``vidtrack reproduce nh-1d``), on few runs."""

import argparse
import json

import numpy as np
import pytest

from vidtrack.errors import UsageError
from vidtrack.experiments import nh_1d
from vidtrack.filters.grid_bayes import gaussian_transition, grid_predict


def test_window_sums_match_brute_force():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(2, len(nh_1d.GRID)))
    states = np.array([[0.0, 12.3, -480.0, 499.5, 700.0], [-3.7, 450.2, -550.0, 49.9, 0.5]])
    got = nh_1d.window_sums(values, states)
    for r in range(2):
        for k, x in enumerate(states[r]):
            mask = np.abs(nh_1d.GRID - x) <= nh_1d.WIDTH
            assert got[r, k] == pytest.approx(values[r, mask].sum(), abs=1e-9)


def test_gaussian_loglik_terms_equal_the_full_gaussian_likelihood_up_to_a_constant():
    rng = np.random.default_rng(1)
    sigma = 2.0
    m = nh_1d.measurements(np.array([30.0]), sigma, 0.0, rng)
    states = np.array([[-100.0, 0.0, 30.0, 77.0]])
    fast = nh_1d.window_sums(nh_1d.gaussian_loglik_weights(m, sigma), states)[0]
    full = np.array([-np.sum((m[0] - (np.abs(nh_1d.GRID - x) <= nh_1d.WIDTH)) ** 2) / (2 * sigma ** 2)
                     for x in states[0]])
    assert np.allclose(fast - fast[0], full - full[0])


def test_banded_transition_matches_dense_prediction():
    p = np.zeros(len(nh_1d.GRID))
    p[[10, 500, 990]] = [0.2, 0.5, 0.3]
    dense = grid_predict(p, gaussian_transition(nh_1d.GRID, 2.0))
    banded = nh_1d.banded_random_walk(2.0) @ p
    assert np.allclose(dense, banded, atol=1e-10)


def test_measurement_noise_has_the_mixture_spread():
    rng = np.random.default_rng(2)
    z = np.zeros(200)
    noise = nh_1d.measurements(z, 1.0, 0.2, rng) - (np.abs(nh_1d.GRID) <= nh_1d.WIDTH)
    # var = (1 - rho) sigma^2 + rho (10 sigma)^2 = 0.8 + 20
    assert np.var(noise) == pytest.approx(20.8, rel=0.05)


def test_true_paths_move_at_most_one_per_step():
    z = nh_1d.true_paths(20, 200, np.random.default_rng(3))
    assert np.all(z[:, 0] == 0) and np.all(np.abs(np.diff(z, axis=1)) <= 1.0 + 1e-12)


def test_paper_path_moves_then_rests_with_the_rms_the_papers_blind_pf_implies():
    z = nh_1d.paper_path(200)
    assert z[0] == 0 and np.all(np.diff(z[:100]) == 1) and np.all(z[100:] == 100)
    assert np.sqrt(np.mean(z ** 2)) == pytest.approx(81.7, abs=1.0)   # the paper's PF rows: 81.70


def _args(**kw):
    base = dict(runs=4, seed=0, rhos="0,0.2", sigmas="1", steps=120, plot=None, plot_rho=0.2,
                nh_init="prior", true_path="ramp")
    base.update(kw)
    return argparse.Namespace(**base)


def test_run_reproduces_the_qualitative_result_on_few_runs():
    result = nh_1d.run(_args(), lambda it, **kw: it)
    json.dumps(result)  # JSON-able
    rows = {row["rho"]: row for row in result["rows"]}
    assert set(rows) == {0.0, 0.2}
    assert rows[0.0]["Bayes"]["mean"] < 2.0          # correct model: Bayes is excellent
    assert rows[0.2]["NH"]["mean"] < 4.0             # NH is robust to outliers
    assert rows[0.2]["Bayes"]["mean"] > 2 * rows[0.2]["NH"]["mean"]
    table = nh_1d.format_table(result)
    assert "Low Noise" in table and "0.20" in table


def test_papers_float64_pf_goes_blind_with_outliers_and_the_log_pf_does_not():
    result = nh_1d.run(_args(rhos="0,0.05", steps=200), lambda it, **kw: it)
    rows = {row["rho"]: row for row in result["rows"]}
    path_rms = np.sqrt(np.mean(nh_1d.paper_path(200) ** 2))
    # rho = 0: both PFs follow the target like the exact filter does
    assert rows[0.0]["PF"]["mean"] < 2.0 and rows[0.0]["PF-log"]["mean"] < 2.0
    # rho = 0.05: every particle's float64 likelihood underflows, the PF stays
    # near z_1 = 0 and its RMSE is the path's RMS (the paper's 81.70 rows)
    assert rows[0.05]["PF"]["mean"] == pytest.approx(path_rms, abs=4.0)
    assert rows[0.05]["PF"]["mean"] > 5 * rows[0.05]["Bayes"]["mean"]
    assert rows[0.05]["PF-log"]["mean"] < rows[0.05]["Bayes"]["mean"] + 2.0


def test_random_true_paths_differ_between_runs():
    one = nh_1d.simulate(1.0, 0.0, 3, [0, 0], T=50, keep_paths=3)
    truths = np.array(one["paths"]["truth"])
    assert not np.allclose(truths[0], truths[1])
    shared = nh_1d.simulate(1.0, 0.0, 3, [0, 0], T=50, keep_paths=3, true_path=nh_1d.paper_path(50))
    assert np.allclose(np.array(shared["paths"]["truth"]), nh_1d.paper_path(50))


def test_bad_arguments_raise_usage_errors():
    with pytest.raises(UsageError):
        nh_1d.run(_args(rhos="0,x"), lambda it, **kw: it)
    with pytest.raises(UsageError):
        nh_1d.run(_args(sigmas="-1"), lambda it, **kw: it)


# ------------------------------------------------------------------ the CLI


def test_reproduce_help_shows_the_experiments_own_options(capsys):
    from vidtrack.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "nh-1d", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "--true-path" in out and "--plot" in out and "--runs" in out


def test_reproduce_nh_1d_writes_the_issues_json_layout(tmp_path, capsys):
    from vidtrack.cli import main

    out = tmp_path / "t.json"
    assert main(["reproduce", "nh-1d", "--runs", "2", "--rhos", "0,0.05", "--sigmas", "1", "--steps", "40",
                 "--json", str(out), "-q"]) == 0
    table = capsys.readouterr().out
    assert "Low Noise (sigma_o = 1)" in table and "PF-log" in table
    rows = json.loads(out.read_text())["rows"]
    assert [(r["sigma_o"], r["rho"]) for r in rows] == [(1.0, 0.0), (1.0, 0.05)]
    for row in rows:
        for name in ("NH", "Bayes", "PF", "PF-log"):
            assert set(row[name]) == {"mean", "sd"} and np.isfinite(row[name]["mean"])


def test_reproduce_unknown_experiment_is_one_line_exit_2(capsys):
    from vidtrack.cli import main

    assert main(["reproduce", "nh-2d"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown experiment" in err[0]
