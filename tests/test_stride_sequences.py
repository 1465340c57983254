"""scripts/stride_sequences.py: every k-th frame with its own box, so the target moves k times as far per frame."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from conftest import REPO, load_script, read_rows
from vidtrack.eval.synthetic import write_sequence


@pytest.fixture(scope="module")
def stride():
    return load_script("stride_sequences")


def test_the_kept_frames_are_the_original_frames_with_their_boxes(stride, tmp_path):
    source = tmp_path / "src"
    truth = write_sequence(source / "Moving", frames=10, velocity=(2.0, 1.0))
    assert stride.main([str(source), str(tmp_path / "out"), "--stride", "3"]) == 0
    out = tmp_path / "out" / "Moving"
    rows = read_rows(out / "groundtruth_rect.txt")
    images = sorted((out / "img").iterdir())
    assert len(images) == len(rows) == 4                                # frames 0, 3, 6, 9
    np.testing.assert_allclose(rows - [1, 1, 0, 0], truth[[0, 3, 6, 9]], atol=0.01)
    originals = sorted((source / "Moving" / "img").iterdir())
    for written, original in zip(images, originals[::3]):
        assert np.array_equal(cv2.imread(str(written)), cv2.imread(str(original)))
    step = np.diff(rows[:, :2], axis=0)                                 # the motion per frame, three times the original
    np.testing.assert_allclose(step, [[6.0, 3.0]] * 3, atol=0.01)


def test_only_annotated_frames_among_those_kept_carry_a_box(stride, tmp_path):
    source = tmp_path / "src"
    write_sequence(source / "Sparse", frames=21, annotate_every=5)
    assert stride.main([str(source), str(tmp_path / "out"), "--stride", "2"]) == 0
    rows = read_rows(tmp_path / "out" / "Sparse" / "groundtruth_rect.txt")
    assert len(rows) == 11                                              # frames 0, 2, ..., 20
    annotated = np.nonzero(rows[:, 2] > 0)[0]
    np.testing.assert_array_equal(annotated, [0, 5, 10])                # frames 0, 10 and 20


def test_a_stride_of_one_copies_every_frame(stride, tmp_path):
    write_sequence(tmp_path / "src" / "Still", frames=5, velocity=(0.0, 0.0))
    assert stride.main([str(tmp_path / "src"), str(tmp_path / "out"), "--stride", "1"]) == 0
    assert len(list((tmp_path / "out" / "Still" / "img").iterdir())) == 5


def test_bad_stride_and_a_copy_inside_the_repository_are_refused(stride, tmp_path):
    write_sequence(tmp_path / "src" / "Still", frames=3)
    with pytest.raises(SystemExit, match="positive"):
        stride.main([str(tmp_path / "src"), str(tmp_path / "out"), "--stride", "0"])
    with pytest.raises(SystemExit, match="outside the repository"):
        stride.main([str(tmp_path / "src"), str(REPO / "stride-copy")])
    assert not (REPO / "stride-copy").exists()
