"""scripts/edge_sequences.py: a crop window that keeps the target at its side, and the boxes moved into it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from conftest import copied_sequence, load_script, red_extent


@pytest.fixture(scope="module")
def edge():
    return load_script("edge_sequences")


def test_missing_rows_are_interpolated_between_annotated_ones(edge):
    boxes = np.array([[0, 0, 10, 10], [0, 0, 0, 0], [0, 0, 0, 0], [30, 6, 10, 10], [0, 0, 0, 0]], float)
    track = edge.interpolated_boxes(boxes, np.array([1, 0, 0, 1, 0], bool))
    np.testing.assert_allclose(track[:, 0], [0, 10, 20, 30, 30])
    np.testing.assert_allclose(track[:, 1], [0, 2, 4, 6, 6])


def test_the_window_follows_the_side_the_target_starts_nearer(edge):
    boxes = np.array([[40, 0, 20, 10], [60, 0, 20, 10], [150, 0, 20, 10]], float)
    # the left half: the window's left side sits gap box widths before the box, inside the frame
    np.testing.assert_allclose(edge.window_origins(boxes, 200, 100, 0.0), [40, 60, 100])
    np.testing.assert_allclose(edge.window_origins(boxes, 200, 100, -0.5), [50, 70, 100])
    # the right half: the box's right side sits at the window's right side
    right = boxes[::-1]
    np.testing.assert_allclose(edge.window_origins(right, 200, 100, 0.0), [70, 0, 0])


def test_a_box_across_the_window_side_is_clipped(edge):
    assert edge.crop_box((45, 8, 20, 10), 50, 100) == (0.0, 8.0, 15.0, 10.0)
    assert edge.crop_box((140, 8, 20, 10), 50, 100) == (90.0, 8.0, 10.0, 10.0)


def test_the_copy_keeps_the_moving_target_at_the_window_side(edge, tmp_path):
    truth, images = copied_sequence(edge, tmp_path, "Moving", ["--fraction", "0.5", "--gap", "-0.2"], frames=21,
                                    size=(200, 100), box=(20, 40, 30, 20), velocity=(3.0, 0.5))
    assert len(images) == len(truth) == 21
    for row in (0, 10, 20):
        image = cv2.imread(str(images[row]))
        assert image.shape[1] == 100
        box = truth[row] - [1, 1, 0, 0]
        np.testing.assert_allclose(box[[0, 2]], [0, 24], atol=1.0)   # a fifth of the target out of view
        seen = red_extent(image)
        assert np.all(np.abs(seen - box) <= 1.5), (row, seen, box)
