"""scripts/zoom_sequences.py: frames and ground truth under the same known zoom."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from conftest import copied_sequence, load_script, red_extent


@pytest.fixture(scope="module")
def zoom():
    return load_script("zoom_sequences")


def test_zoom_factor_starts_at_one_and_reaches_one_minus_depth_half_a_period_later(zoom):
    assert zoom.zoom_factor(0, 0.4, 100) == pytest.approx(1.0)
    assert zoom.zoom_factor(50, 0.4, 100) == pytest.approx(0.6)
    assert zoom.zoom_factor(100, 0.4, 100) == pytest.approx(1.0)


def test_the_written_box_follows_the_zoomed_target(zoom, tmp_path):
    truth, images = copied_sequence(zoom, tmp_path, "Still", ["--depth", "0.5", "--period", "40"], frames=21,
                                    size=(160, 120), box=(90, 60, 40, 30), velocity=(0.0, 0.0))
    assert len(images) == len(truth) == 21
    np.testing.assert_allclose(truth[0], [91, 61, 40, 30])             # z = 1: unchanged (1-based)
    np.testing.assert_allclose(truth[20, 2:], [20, 15])                 # z = 0.5 half a period in
    for row in (0, 10, 20):
        seen = red_extent(cv2.imread(str(images[row])))
        box = truth[row] - [1, 1, 0, 0]
        assert np.all(np.abs(seen - box) <= 1.5), (row, seen, box)
