"""scripts/occlude_sequences.py: a bar passes in front of the target at known frames; the ground truth is kept."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import load_script
from vidtrack.eval.synthetic import write_sequence


@pytest.fixture(scope="module")
def occlude():
    return load_script("occlude_sequences")


def frames_of(folder: Path) -> list[np.ndarray]:
    return [cv2.imread(str(path)) for path in sorted(folder.iterdir())]


@pytest.fixture
def copied(occlude, tmp_path):
    """A 100-frame moving target, copied with crossings at frames 20 and 60 (8 frames each, bar 1.5 targets wide)."""
    source = tmp_path / "src"
    write_sequence(source / "Walker", frames=100, size=(200, 120), box=(30, 40, 20, 24), velocity=(1.0, 0.2))
    argv = [str(source), str(tmp_path / "out"), "--first", "20", "--period", "40", "--duration", "8",
            "--width", "1.5"]
    assert occlude.main(argv) == 0
    return source / "Walker", tmp_path / "out" / "Walker"


def test_the_bar_hides_the_whole_target_at_each_crossing_and_nothing_far_from_one(copied):
    source, out = copied
    before, after = frames_of(source / "img"), frames_of(out / "img")
    truth = np.loadtxt(out / "groundtruth_rect.txt", delimiter=",")
    assert len(after) == len(before) == len(truth) == 100
    for k in (20, 60):
        x, y, w, h = (int(round(v)) for v in truth[k] - [1, 1, 0, 0])
        unchanged = np.all(after[k][y:y + h, x:x + w] == before[k][y:y + h, x:x + w], axis=2)
        assert unchanged.mean() < 0.02, k
    for k in (0, 40, 90):   # more than twice a duration away from both crossings
        assert np.array_equal(after[k], before[k]), k


def test_the_bar_moves_across_the_target_in_alternating_directions(copied):
    source, out = copied
    before, after = frames_of(source / "img"), frames_of(out / "img")

    def bar_centre(k: int) -> float:
        columns = np.flatnonzero(np.any(after[k] != before[k], axis=(0, 2)))
        return float(columns.mean())

    first = bar_centre(22) - bar_centre(18)
    second = bar_centre(62) - bar_centre(58)
    assert first / 4 == pytest.approx(1.0 + 50 / 8, abs=0.5)      # the target's speed plus the crossing's
    assert second / 4 == pytest.approx(1.0 - 50 / 8, abs=0.5)


def test_the_ground_truth_is_kept(copied):
    source, out = copied
    np.testing.assert_allclose(np.loadtxt(out / "groundtruth_rect.txt", delimiter=","),
                               np.loadtxt(source / "groundtruth_rect.txt", delimiter=","), atol=0.01)


def test_crossings_are_placed_from_the_nearest_annotated_row(occlude):
    truth = np.zeros((50, 4))
    annotated = np.zeros(50, bool)
    annotated[::5] = True
    truth[::5] = [[10.0 + 2 * k, 5.0, 8.0, 8.0] for k in range(10)]
    plan = occlude.plan_crossings(truth, annotated, first=11, period=30, duration=6.0, width=2.0,
                                  rng=np.random.default_rng(0))
    assert [c.frame for c in plan] == [11, 41]
    assert plan[0].centre_x == pytest.approx(10.0 + 2 * 2 + 4.0)   # row 10's box centre
    assert plan[0].speed == pytest.approx(0.4 + (16.0 + 8.0) / 6.0)   # the target's 0.4 pixels a frame, plus
    assert plan[1].speed == pytest.approx(0.4 - (16.0 + 8.0) / 6.0)


@pytest.mark.parametrize("args", [["--width", "1.0"], ["--duration", "0"], ["--period", "40", "--duration", "24"]])
def test_a_bar_that_cannot_hide_the_target_or_crossings_that_overlap_are_refused(occlude, tmp_path, args):
    write_sequence(tmp_path / "src" / "Still", frames=3)
    with pytest.raises(SystemExit, match="need"):
        occlude.main([str(tmp_path / "src"), str(tmp_path / "out"), *args])



@pytest.mark.parametrize("mode", ["target", "random"])
def test_a_target_coloured_bar_takes_one_of_the_targets_colours(occlude, tmp_path, mode):
    """``--bar-colour target``: the middle of each bar (lit head-on) has a colour of the target's first frame.

    The synthetic target is red and yellow; a random bar (each channel in 40 .. 200) is neither.
    """
    source = tmp_path / "src"
    write_sequence(source / "Walker", frames=100, size=(200, 120), box=(30, 40, 20, 24), velocity=(1.0, 0.2))
    argv = [str(source), str(tmp_path / "out"), "--first", "20", "--period", "40", "--duration", "8",
            "--width", "1.5", "--bar-colour", mode]
    assert occlude.main(argv) == 0
    before, after = frames_of(source / "Walker" / "img"), frames_of(tmp_path / "out" / "Walker" / "img")
    target = before[0][40:40 + 24, 30:30 + 20].reshape(-1, 3).astype(float)
    for k in (20, 60):
        columns = np.flatnonzero(np.any(after[k] != before[k], axis=(0, 2)))
        middle = after[k][:, columns[len(columns) // 2]].astype(float).mean(axis=0)
        nearest = np.min(np.linalg.norm(target - middle, axis=1))
        assert (nearest < 25) == (mode == "target"), (k, middle, nearest)
