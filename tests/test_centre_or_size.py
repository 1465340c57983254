"""What a run's centre and its size cost it: recentred boxes, fixed-size ground truth, scripts/centre_or_size.py."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script
from vidtrack.eval.datasets import load_dataset
from vidtrack.eval.metrics import fixed_size, recentred, success_auc
from vidtrack.eval.scoring import centre_and_size_aucs
from vidtrack.eval.synthetic import write_sequence

#: Success AUC of a perfect box: IoU 1 passes every threshold but the last (IoU > 1)
PERFECT = 20 / 21


def test_recentred_keeps_the_sizes_and_takes_the_other_boxes_centres():
    boxes = np.array([[0.0, 0.0, 10.0, 20.0], [5.0, 5.0, 4.0, 4.0]])
    centres_from = np.array([[100.0, 50.0, 30.0, 40.0], [0.0, 0.0, 2.0, 2.0]])
    out = recentred(boxes, centres_from)
    np.testing.assert_allclose(out, [[110.0, 60.0, 10.0, 20.0], [-1.0, -1.0, 4.0, 4.0]])
    np.testing.assert_allclose(boxes, [[0.0, 0.0, 10.0, 20.0], [5.0, 5.0, 4.0, 4.0]])   # inputs untouched
    with pytest.raises(ValueError, match="2 boxes for 1 centres"):
        recentred(boxes, centres_from[:1])


def test_fixed_size_looks_at_the_annotated_rows_only():
    assert fixed_size([[1, 2, 30, 40], [0, 0, 0, 0], [9, 8, 30, 40]])
    assert not fixed_size([[1, 2, 30, 40], [0, 0, 0, 0], [9, 8, 31, 40]])
    assert not fixed_size([[0, 0, 0, 0]])


@pytest.fixture
def data(tmp_path):
    """A 20-frame generated sequence whose ground truth grows by one pixel a side from row 10."""
    write_sequence(tmp_path / "data" / "Walk", frames=20, size=(160, 120), box=(20, 30, 20, 24))
    path = tmp_path / "data" / "Walk" / "groundtruth_rect.txt"
    rows = np.loadtxt(path, delimiter=",")
    rows[10:, 2:] += 1.0
    path.write_text("".join(",".join(f"{v:g}" for v in row) + "\n" for row in rows))
    return tmp_path


def test_a_perfect_centre_or_a_perfect_size_scores_as_such(data):
    sequence = load_dataset(data / "data", ["Walk"])[0]
    truth = sequence.ground_truth
    mask = np.ones(len(truth), bool)
    half = recentred(truth * [1, 1, 0.5, 0.5], truth)           # true centres, half the size
    auc, true_size, true_centre = centre_and_size_aucs(sequence, half, mask)
    assert true_size == pytest.approx(PERFECT) and true_centre == pytest.approx(auc)
    assert auc == pytest.approx(success_auc(np.full(len(truth), 0.25)))
    shifted = truth + [5.0, 0.0, 0.0, 0.0]                      # the true size, 5 px to the right
    auc, true_size, true_centre = centre_and_size_aucs(sequence, shifted, mask)
    assert true_centre == pytest.approx(PERFECT) and true_size == pytest.approx(auc) and auc < PERFECT


@pytest.fixture
def run(data):
    """A run of one tracker on ``data``: the true boxes, half their size from row 10 on."""
    truth = np.loadtxt(data / "data" / "Walk" / "groundtruth_rect.txt", delimiter=",")
    result = truth.copy()
    result[10:] = recentred(truth[10:] * [1, 1, 0.5, 0.5], truth[10:])
    out = data / "run" / "mytracker"
    out.mkdir(parents=True)
    (out / "Walk.txt").write_text("".join(",".join(f"{v:g}" for v in row) + "\n" for row in result))
    return data


def test_the_script_prints_each_sequence_its_three_aucs(run, capsys):
    script = load_script("centre_or_size")
    assert script.main([str(run / "run"), str(run / "data")]) == 0
    text = capsys.readouterr().out
    expected = success_auc(np.r_[np.ones(10), np.full(10, 0.25)])
    assert "## `mytracker`" in text
    assert f"| Walk | {expected:.3f} | {PERFECT:.3f} | {expected:.3f} | varies |" in text
    assert f"| **mean** | {expected:.3f} | {PERFECT:.3f} | {expected:.3f} | |" in text


def test_the_script_marks_ground_truth_of_one_size(tmp_path, capsys):
    truth = write_sequence(tmp_path / "data" / "Still", frames=10, size=(96, 72))
    out = tmp_path / "run" / "mytracker"
    out.mkdir(parents=True)
    (out / "Still.txt").write_text("".join(",".join(f"{v:g}" for v in row) + "\n" for row in truth + [1, 1, 0, 0]))
    assert load_script("centre_or_size").main([str(tmp_path / "run"), str(tmp_path / "data")]) == 0
    assert "| one for all frames |" in capsys.readouterr().out


def test_the_script_stops_with_one_line_on_bad_input(tmp_path):
    script = load_script("centre_or_size")
    (tmp_path / "run" / "empty").mkdir(parents=True)
    with pytest.raises(SystemExit, match=r"^centre_or_size: .*no tracker with result files$"):
        script.main([str(tmp_path / "run"), str(tmp_path)])
    with pytest.raises(SystemExit, match=r"^centre_or_size: .*: not a folder$"):
        script.main([str(tmp_path / "missing"), str(tmp_path)])
    with pytest.raises(SystemExit, match=r"^centre_or_size: .*other: no result files$"):
        script.main([str(tmp_path / "run"), str(tmp_path), "--filter", "other"])
    (tmp_path / "run" / "empty" / "Nowhere.txt").write_text("1,2,3,4\n")
    with pytest.raises(SystemExit, match=r"^centre_or_size: "):
        script.main([str(tmp_path / "run"), str(tmp_path / "nodata")])
