"""Failure spans: the runs of scored frames that miss the target, from the function and from scripts/failure_spans.py."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script
from vidtrack.eval.confidence import failure_spans, format_confidence
from vidtrack.eval.synthetic import write_sequence


def test_spans_are_the_runs_of_missed_frames_with_their_confidence_and_lost_share():
    rows = [1, 5, 10, 15, 20, 25, 30, 35]
    ious = [0.6, 0.0, 0.0, 0.4, 0.0, 0.0, 0.0, 0.7]
    confidence = [0.9, 0.2, 0.4, 0.8, 0.9, 0.7, 0.5, 0.9]
    status = ["tracking", "lost", "tracking", "tracking", "tracking", "tracking", "lost", "tracking"]
    spans = failure_spans(rows, ious, confidence, status)
    assert [(s["first"], s["last"], s["frames"]) for s in spans] == [(5, 10, 2), (20, 30, 3)]
    assert spans[0]["confidence"] == pytest.approx(0.3) and spans[0]["lost"] == pytest.approx(0.5)
    assert spans[1]["confidence"] == pytest.approx(0.7) and spans[1]["lost"] == pytest.approx(1 / 3)


def test_a_miss_at_either_end_is_a_span_and_no_miss_gives_none():
    spans = failure_spans([0, 1, 2, 3], [0.0, 0.5, 0.5, 0.0], [0.1, 0.9, 0.9, 0.3], ["lost"] * 4)
    assert [(s["first"], s["last"]) for s in spans] == [(0, 0), (3, 3)]
    assert failure_spans([0, 1], [0.5, 0.8], [0.9, 0.9], ["tracking"] * 2) == []


@pytest.fixture
def run(tmp_path):
    """A 30-frame sequence and a run of one tracker whose box leaves the target on rows 10-17, at confidence 0.2."""
    write_sequence(tmp_path / "data" / "Walk", frames=30, size=(160, 120), box=(20, 30, 20, 24))
    truth = (tmp_path / "data" / "Walk" / "groundtruth_rect.txt").read_text().splitlines()
    lines, rows = [], []
    for row, line in enumerate(truth):
        away = 10 <= row <= 17
        lines.append("130,90,20,24" if away else line)
        rows.append((row, 0.2 if away else 0.9, "lost" if row in (16, 17) else "tracking", 1))
    out = tmp_path / "run" / "mytracker"
    out.mkdir(parents=True)
    (out / "Walk.txt").write_text("\n".join(lines) + "\n")
    (out / "Walk.confidence.csv").write_text(format_confidence(rows))
    return tmp_path


def test_the_script_lists_the_span_and_the_share_the_confidence_saw(run, capsys):
    script = load_script("failure_spans")
    assert script.main([str(run / "run"), str(run / "data")]) == 0
    text = capsys.readouterr().out
    assert "## `mytracker`" in text
    assert "| Walk | 10-17 | 8 | 0.20 | 0.25 |" in text
    assert "8 of 29 scored frames miss the target; 1.00 of them in spans of mean confidence below 0.5." in text


def test_the_script_stops_with_one_line_on_a_run_without_confidence_files(tmp_path):
    (tmp_path / "run" / "empty").mkdir(parents=True)
    script = load_script("failure_spans")
    with pytest.raises(SystemExit, match=r"^failure_spans: .*no tracker with per-frame confidence files$"):
        script.main([str(tmp_path / "run"), str(tmp_path)])
    with pytest.raises(SystemExit, match=r"^failure_spans: .*: not a folder$"):
        script.main([str(tmp_path / "missing"), str(tmp_path)])


def test_the_init_frame_is_not_scored(run):
    script = load_script("failure_spans")
    from vidtrack.eval.datasets import load_dataset
    sequence = load_dataset(run / "data", ["Walk"])[0]
    spans, scored = script.sequence_spans(sequence, run / "run", "mytracker")
    assert scored == 29 and len(spans) == 1
    assert np.isclose(spans[0]["confidence"], 0.2)
