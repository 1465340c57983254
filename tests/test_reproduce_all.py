"""The papers' values beside vidtrack's, and ``vidtrack reproduce all --out DIR``."""

import json

import numpy as np
import pytest

from vidtrack.cli import main
from vidtrack.experiments import cbt_detections
from vidtrack.experiments.paper import cell, comparison, relative_difference
from vidtrack.channels import ChannelBasis
from vidtrack.learn.baum_welch import baum_welch, chain_counts


def test_relative_difference_and_cells():
    assert relative_difference(11.0, 10.0) == pytest.approx(0.1)
    assert relative_difference(1.0, None) is None and relative_difference(1.0, 0.0) is None
    assert cell(23.68, 22.41).strip() == "23.68 (22.41, +5.7%)"
    assert cell(1.0, None).strip() == "1.00 (-)"
    c = comparison("Table 1", "SVK", "whole", 9.0, 10.0)
    assert c == {"table": "Table 1", "row": "SVK", "column": "whole", "vidtrack": 9.0, "paper": 10.0,
                 "rel_diff": pytest.approx(-0.1)}


def test_labels_do_not_change_the_simulation_and_associated_counts_use_true_chains_only():
    sc = cbt_detections.Scenario(frames=30, clutter_rate=4.0)
    tracks, dets = cbt_detections.simulate(np.random.default_rng(3), sc)
    tracks2, dets2, owners = cbt_detections.simulate(np.random.default_rng(3), sc, labels=True)
    assert np.array_equal(tracks, tracks2) and all(np.array_equal(a, b) for a, b in zip(dets, dets2))
    assert all(len(o) == len(d) for o, d in zip(owners, dets)) and any((o == -1).any() for o in owners)
    bases = (ChannelBasis(0.0, cbt_detections.WIDTH, 10), ChannelBasis(0.0, cbt_detections.HEIGHT, 10))
    G = cbt_detections.learn_associated(dets, owners, bases, 1, sc.objects)
    own = [sum(c for c in chain_counts([d[w == o, :2] for d, w in zip(dets, owners)], bases, 1, np.inf)[:1])
           for o in range(sc.objects)]
    assert np.allclose(G[0], (own[0] + own[1] + 1e-6) / (own[0] + own[1] + 1e-6).sum(axis=0, keepdims=True))


def test_baum_welch_prior_weight_keeps_unvisited_histories():
    rng = np.random.default_rng(0)
    G0 = rng.random((6, 6)) + 0.1
    G0 /= G0.sum(axis=0, keepdims=True)
    z = np.zeros((40, 6))
    z[:, 2] = 1.0  # the posterior only ever visits channel 2
    ml = baum_welch([z], G0, np.eye(6), iterations=2, learn_H=False)
    mapped = baum_welch([z], G0, np.eye(6), iterations=2, learn_H=False, prior_weight=1.0)
    assert np.allclose(ml.G[:, 5], 1.0 / 6, atol=1e-3)  # ML: a never-visited column becomes uniform
    assert np.allclose(mapped.G[:, 5], G0[:, 5], atol=1e-3)  # MAP: it keeps the starting estimate
    assert np.allclose(mapped.G.sum(axis=0), 1.0)


def test_reproduce_all_writes_the_report_with_the_claims_first(tmp_path, capsys, monkeypatch):
    from vidtrack.experiments import report as all_report

    monkeypatch.setitem(all_report.RUNS, "cbt-carlin", 10)   # the report's layout, not the RMSE over 100 runs
    out = tmp_path / "r"
    assert main(["reproduce", "all", "--out", str(out), "--only", "cbt-carlin", "-q"]) == 0
    report = (out / "report.md").read_text()
    head = report.split("## cbt-carlin")[0]
    assert "## Claims:" in head and "| experiment | claim | holds |" in head and "Baum-Welch" in head
    assert (out / "cbt-carlin-trajectories.png").stat().st_size > 1000
    assert "![cbt-carlin" in report
    result = json.loads((out / "cbt-carlin.json").read_text())
    assert {c["row"] for c in result["vs_paper"]} == {"EKF", "Grid", "SIR PF", "CBT"}
    assert all({"claim", "holds", "detail"} <= set(c) for c in result["claims"])


def test_reproduce_all_bad_input_is_one_line_exit_2(tmp_path, capsys):
    assert main(["reproduce", "all", "--out", str(tmp_path), "--only", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vidtrack: error: unknown experiment") and "\n" not in err
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "all"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "--out" in err and "\n" not in err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["reproduce", "all", "--out", str(blocker / "sub"), "--only", "cbt-carlin", "-q"]) == 2
    assert "\n" not in capsys.readouterr().err.strip()
