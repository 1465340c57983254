"""Confidence metrics: hand-made frames with known answers, the per-frame file, and an evaluation
whose tracker reports a known confidence and status."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from vidtrack.eval import confidence as conf
from vidtrack.eval.datasets import load_dataset
from vidtrack.eval.evaluation import run_evaluation
from vidtrack.eval.synthetic import write_sequence
from vidtrack.recipes import Recipe, registry
from vidtrack.types import Box, TrackState


def test_false_lost_and_missed_loss_count_the_right_frames():
    ious = [0.8, 0.0, 0.3, 0.0, 0.9, 0.0]
    status = ["tracking", "tracking", "lost", "lost", "tracking", "lost"]
    assert conf.false_lost(ious, status) == pytest.approx(1 / 3)  # lost: 0.3 (overlaps), 0.0, 0.0
    assert conf.missed_loss(ious, status) == pytest.approx(1 / 3)  # tracking: 0.8, 0.0 (missed), 0.9
    assert math.isnan(conf.false_lost([0.5], ["tracking"]))  # nothing marked lost: undefined
    assert math.isnan(conf.missed_loss([0.5], ["lost"]))


def test_roc_auc_known_values_and_ties():
    assert conf.roc_auc([0.9, 0.8, 0.1, 0.2], [True, True, False, False]) == 1.0
    assert conf.roc_auc([0.1, 0.2, 0.9, 0.8], [True, True, False, False]) == 0.0
    assert conf.roc_auc([0.5, 0.5, 0.5], [True, False, False]) == 0.5  # ties count one half
    # positives 0.9, 0.3; negatives 0.95, 0.2: pairs won 0.9>0.2, 0.3>0.2 -> 2 of 4
    assert conf.roc_auc([0.9, 0.3, 0.95, 0.2], [True, True, False, False]) == 0.5
    assert math.isnan(conf.roc_auc([0.1, 0.2], [True, True]))


def test_ok_flag_baseline_and_pooling():
    ious = np.array([0.9, 0.7, 0.0, 0.0])
    measured = np.array([True, True, True, False])  # an ok flag that stays True once the target has gone
    flag = conf.ok_flag_metrics(ious, measured)
    assert flag["missed_loss"] == pytest.approx(1 / 3) and flag["false_lost"] == 0.0
    assert flag["lost_rate"] == 0.25 and flag["confidence_auc"] == pytest.approx(0.75)  # (1 + 0.5) / 2
    a = (np.array([0.9, 0.0]), np.array([0.8, 0.1]), np.array(["tracking", "lost"]), np.array([True, True]))
    b = (np.array([0.6]), np.array([0.05]), np.array(["lost"]), np.array([True]))
    pooled = conf.pooled_metrics([a, b], ok_flag=True)
    assert pooled["false_lost"] == 0.5 and pooled["lost_rate"] == pytest.approx(2 / 3)
    assert pooled["confidence_auc"] == 0.5  # 0.8 beats 0.1, 0.05 loses to 0.1: pooled, not per sequence
    assert set(pooled["ok_flag"]) == set(conf.CONFIDENCE_KEYS)
    assert all(math.isnan(v) for v in conf.pooled_metrics([]).values())


def test_confidence_file_round_trip(tmp_path):
    path = conf.confidence_path(tmp_path / "mil" / "Girl.txt")
    assert path.name == "Girl.confidence.csv"
    path.parent.mkdir()
    path.write_text(conf.format_confidence([(2, 1.0, "tracking", True), (3, 0.25, "lost", False)]))
    confidence, status, measured = conf.read_confidence(path, 5)
    assert np.isnan(confidence[[0, 1, 4]]).all() and list(confidence[2:4]) == [1.0, 0.25]
    assert list(status) == ["", "", "tracking", "lost", ""] and list(measured) == [False, False, True, False, False]
    path.write_text(conf.HEADER + "\n9,0.5,tracking,1\n")
    with pytest.raises(conf.DatasetError, match="out of range"):
        conf.read_confidence(path, 5)


class ScriptedTracker:
    """Follows the true box on frames 0..9, jumps off the target from frame 10 on; a fixed script
    of confidences and statuses (frame 5 wrongly lost; frames 10, 11 confidently wrong)."""

    def __init__(self, truth) -> None:
        self.truth = truth

    def initialize(self, frame, box):
        return TrackState(frame.index, box, 1.0, "tracking", measured=box)

    def step(self, frame):
        k = frame.index
        x, y, w, h = self.truth[k]
        box = Box(x, y, w, h) if k < 10 else Box(x + w + 5, y, w, h)
        confidence = {5: 0.3, 10: 0.95, 11: 0.95}.get(k, 0.9 if k < 10 else 0.2)
        status = "lost" if k == 5 or k >= 12 else "tracking"
        return TrackState(k, box, confidence, status, measured=box if k < 15 else None)


def test_evaluation_scores_a_scripted_confidence(tmp_path, monkeypatch):
    truth = write_sequence(tmp_path / "data" / "Otb", layout="otb", frames=20, size=(120, 72))
    monkeypatch.setitem(registry(), "test-scripted", Recipe("test", lambda config, seed=None: ScriptedTracker(truth)))
    sequences = load_dataset(tmp_path / "data")
    out = tmp_path / "out"
    evaluation = run_evaluation(sequences, ["test-scripted"], out, isolate=False)
    lines = (out / "test-scripted" / "Otb.confidence.csv").read_text().splitlines()
    assert lines[0] == conf.HEADER and lines[1] == "0,1,tracking,1" and lines[6] == "5,0.3,lost,1"
    assert lines[16] == "15,0.2,lost,0" and len(lines) == 21
    row = evaluation.summary["test-scripted"]["Otb"]
    # scored: frames 1..19 (the init frame is given). lost: 5 (IoU 1) and 12..19 (IoU 0) -> 1/9 false;
    # tracking: 1-4, 6-9 (IoU 1), 10, 11 (IoU 0) -> 2/10 missed
    assert row["false_lost"] == pytest.approx(1 / 9) and row["missed_loss"] == pytest.approx(0.2)
    assert row["lost_rate"] == pytest.approx(9 / 19)
    # positives (IoU > 0.5): eight at 0.9, one at 0.3; negatives: two at 0.95, eight at 0.2 -> (64 + 8) / 90
    assert row["confidence_auc"] == pytest.approx(0.8)
    mean = evaluation.summary["test-scripted"]["mean"]
    assert mean["confidence_auc"] == pytest.approx(0.8) and "ok_flag" not in mean  # not an opencv-* tracker


def test_opencv_tracker_gets_the_ok_flag_baseline(tmp_path):
    if "opencv-kcf" not in registry():
        pytest.skip("no opencv-kcf")
    write_sequence(tmp_path / "data" / "Otb", layout="otb", frames=12)
    out = tmp_path / "out"
    from vidtrack.eval.report import write_summary

    evaluation = run_evaluation(load_dataset(tmp_path / "data"), ["opencv-kcf"], out, isolate=False)
    write_summary(out, evaluation.summary)
    mean = json.loads((out / "summary.json").read_text())["opencv-kcf"]["mean"]
    assert set(mean["ok_flag"]) == set(conf.CONFIDENCE_KEYS) and 0 <= mean["lost_rate"] <= 1
    assert "OpenCV ok flag" in (out / "summary.md").read_text()


def test_reliability_bins_and_expected_calibration_error():
    confidence = [0.05, 0.15, 0.95, 0.9, 0.55, np.nan]
    good = [False, True, True, True, False, True]
    mean_conf, frac, count = conf.reliability(confidence, good)
    assert count.tolist() == [1, 1, 0, 0, 0, 1, 0, 0, 0, 2]   # NaN left out; 0.95 and 0.9 share the last bin
    assert mean_conf[9] == pytest.approx(0.925) and frac[9] == 1.0 and math.isnan(frac[2])
    # |0.05 - 0| + |0.15 - 1| + |0.55 - 0| + 2 |0.925 - 1|, over 5 frames
    assert conf.expected_calibration_error(confidence, good) == pytest.approx((0.05 + 0.85 + 0.55 + 0.15) / 5)
    assert conf.expected_calibration_error([1.0, 0.0], [True, False]) == 0.0   # perfectly calibrated
    assert math.isnan(conf.expected_calibration_error([], []))
    pooled = conf.pooled_metrics([(np.array([0.9, 0.1]), np.array([0.8, 0.3]), np.array(["tracking", "lost"]),
                                   np.array([True, False]))])
    assert pooled["ece"] == pytest.approx((0.2 + 0.3) / 2) and sum(pooled["reliability"]["count"]) == 2


def test_reliability_diagram_is_drawn_from_the_pooled_bins(tmp_path):
    from vidtrack.eval.plots import reliability_plot

    frames = [(np.array([0.9, 0.1, 0.6]), np.array([0.8, 0.3, 0.7]), np.array(["tracking"] * 3),
               np.ones(3, bool))]
    summary = {"a": {"mean": conf.pooled_metrics(frames)}, "b": {"mean": {"auc": 0.5}}}   # b: no bins, no line
    png = reliability_plot(None, summary)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    path = reliability_plot(tmp_path / "reliability.png", summary)
    assert path.read_bytes()[:8] == png[:8]
