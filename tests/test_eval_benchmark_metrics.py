"""Each benchmark's own metrics: normalised precision (LaSOT), GOT-10k's AO / SR0.5 / SR0.75 over present
frames, and the success curve on the benchmark's threshold grid, in summary.json and the tables."""

from __future__ import annotations

import json

import numpy as np
import pytest

from layout_miniatures import SEQUENCES, build_got10k, build_lasot
from vidtrack.cli import main as vidtrack_main
from vidtrack.eval import metrics as M
from vidtrack.eval.datasets import load_dataset, read_boxes


def test_normalized_center_error_divides_each_axis_by_the_truth_size():
    truth = np.array([[0, 0, 10, 20], [0, 0, 0.5, 0.5]], float)
    result = np.array([[5, 10, 10, 20], [3, 4, 0.5, 0.5]], float)
    np.testing.assert_allclose(M.normalized_center_error(result, truth), [np.sqrt(0.5), 5.0])
    assert M.normalized_center_error([[np.nan] * 4], [[0, 0, 1, 1]])[0] == np.inf


def test_normalized_precision_is_the_mean_of_its_curve_over_0_to_half():
    # thresholds 0..0.24 (25 of them) see 1 of 3 frames, 0.25..0.5 (26) see 2 of 3
    assert M.normalized_precision([0.0, 0.25, 1.0]) == pytest.approx((25 / 3 + 26 * 2 / 3) / 51)
    assert len(M.NORM_PRECISION_THRESHOLDS) == 51 and M.NORM_PRECISION_THRESHOLDS[-1] == 0.5


def test_got10k_scores_and_clipping():
    scores = M.got10k_scores([0.2, 0.6, 0.8])
    assert scores == pytest.approx({"ao": 1.6 / 3, "sr50": 2 / 3, "sr75": 1 / 3})
    assert all(np.isnan(v) for v in M.got10k_scores([]).values())
    boxes = np.array([[-5.0, 10, 20, 100], [45, 50, 20, 20]])
    np.testing.assert_array_equal(M.clip_to_frame(boxes, 50, 60), [[0, 10, 20, 50], [45, 50, 5, 10]])
    assert boxes[0, 0] == -5  # the input is not modified


def _run(data, out, *extra):
    return vidtrack_main(["eval", str(data), "--filter", "kalman-cv", "--out", str(out), "--in-process",
                          "--no-plots", "-q", *extra])


def _own_iou(a, b):
    x1, y1 = np.maximum(a[:, 0], b[:, 0]), np.maximum(a[:, 1], b[:, 1])
    x2 = np.minimum(a[:, 0] + a[:, 2], b[:, 0] + b[:, 2])
    y2 = np.minimum(a[:, 1] + a[:, 3], b[:, 1] + b[:, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    return inter / (a[:, 2] * a[:, 3] + b[:, 2] * b[:, 3] - inter)


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_got10k_ao_sr_over_present_frames_pooled_in_the_mean(tmp_path, capsys):
    data = build_got10k(tmp_path)
    out = tmp_path / "out"
    assert _run(data, out) == 0
    table = capsys.readouterr().out
    assert " AO |" in table and "SR0.75" in table and "NormPrec" in table
    page = (out / "report.html").read_text()
    assert all(f"<th>{title}</th>" in page for title in ("AO", "SR0.5", "SR0.75", "NormPrec"))
    summary = json.loads((out / "summary.json").read_text())["kalman-cv"]
    pooled = []
    for seq in load_dataset(data):
        result = read_boxes(out / "kalman-cv" / f"{seq.name}.txt")
        keep = np.ones(len(seq), bool)
        keep[0] = False      # the init frame
        keep[8] = False      # absent (absence.label 1, cover.label 0)
        width, height = seq.frame_size
        ious = _own_iou(M.clip_to_frame(result[keep], width, height),
                        M.clip_to_frame(seq.ground_truth[keep], width, height))
        pooled.append(ious)
        row = summary[seq.name]
        assert row["ao"] == pytest.approx(ious.mean(), abs=1e-12)
        assert row["sr50"] == pytest.approx((ious > 0.5).mean()) and row["sr75"] == pytest.approx((ious > 0.75).mean())
    pooled = np.concatenate(pooled)
    assert summary["mean"]["ao"] == pytest.approx(pooled.mean(), abs=1e-12)
    assert summary["mean"]["sr50"] == pytest.approx((pooled > 0.5).mean())


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_lasot_normalised_precision_in_the_summary_and_no_got10k_columns(tmp_path, capsys):
    data = build_lasot(tmp_path)
    out = tmp_path / "out"
    assert _run(data, out, "--max-frames", "8") == 0
    table = capsys.readouterr().out
    assert "NormPrec" in table and " AO |" not in table
    page = (out / "report.html").read_text()
    assert "<th>NormPrec</th>" in page and "<th>AO</th>" not in page
    summary = json.loads((out / "summary.json").read_text())["kalman-cv"]
    seq = load_dataset(data)[0]
    visible = seq.present[:8]  # row 6 is flagged fully occluded: LaSOT does not score it
    assert visible.sum() == 7
    result = read_boxes(out / "kalman-cv" / f"{seq.name}.txt")[:8][visible]
    truth = seq.ground_truth[:8][visible]
    centre = (result[:, :2] + result[:, 2:] / 2) - (truth[:, :2] + truth[:, 2:] / 2)
    norm = np.hypot(*(centre / truth[:, 2:]).T)
    expected = np.mean([(norm <= t).mean() for t in np.arange(51) / 100])
    assert summary[seq.name]["norm_precision"] == pytest.approx(expected, abs=1e-12)
    assert "ao" not in summary[seq.name]


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_success_curves_on_each_benchmarks_grid(tmp_path):
    from vidtrack.eval.evaluation import run_evaluation

    got = run_evaluation(load_dataset(build_got10k(tmp_path)), ["kalman-cv"], tmp_path / "g", isolate=False,
                         max_frames=4)
    lasot = run_evaluation(load_dataset(build_lasot(tmp_path)), ["kalman-cv"], tmp_path / "l", isolate=False,
                           max_frames=4)
    assert {len(c[0]) for c in got.curves.values()} == {101}
    assert {len(c[0]) for c in lasot.curves.values()} == {21}
