"""Mean-shift on synthetic frames."""

import numpy as np
import pytest

from vidtrack.measure.meanshift import MeanShiftMeasurer, bhattacharyya, bin_image, kernel_histogram, mean_shift
from vidtrack.types import Box, Estimate, Frame

from conftest import synthetic_sequence


def test_histogram_is_normalised_and_similarity_is_one_for_itself():
    frames, boxes = synthetic_sequence(n=1)
    bins = bin_image(frames[0].image, gray=False, bins=16)
    q, mass = kernel_histogram(bins, boxes[0], 16 ** 3)
    assert mass > 0 and q.sum() == pytest.approx(1.0)
    assert bhattacharyya(q, q) == pytest.approx(1.0)


def test_mean_shift_converges_onto_displaced_target():
    frames, boxes = synthetic_sequence(n=1)
    bins = bin_image(frames[0].image, gray=False, bins=16)
    q, _ = kernel_histogram(bins, boxes[0], 16 ** 3)
    start = Box(boxes[0].x + 8, boxes[0].y - 6, boxes[0].w, boxes[0].h)
    found, rho, iterations = mean_shift(bins, q, start)
    assert np.hypot(*(found.center - boxes[0].center)) < 2.0
    assert rho > 0.9 and iterations > 1


def test_measurer_follows_moving_target_and_reports_quality():
    frames, boxes = synthetic_sequence(n=12)
    m = MeanShiftMeasurer()
    m.initialize(frames[0], boxes[0])
    prior = Estimate(boxes[0])
    for frame in frames[1:]:
        meas = m.measure(frame, prior)
        assert meas.box is not None and 0.0 <= meas.quality <= 1.0
        assert meas.stages["backprojection"].ndim == 2
        prior = Estimate(meas.box)
    assert np.hypot(*(meas.box.center - boxes[-1].center)) < 3.0
    assert meas.quality > 0.8


def test_grey_frames_use_intensity_histogram():
    frames, boxes = synthetic_sequence(n=3)
    grey = [Frame(f.index, np.repeat(f.image.mean(axis=2, keepdims=True).astype(np.uint8), 3, axis=2)) for f in frames]
    m = MeanShiftMeasurer()
    m.initialize(grey[0], boxes[0])
    assert m.gray_ and m.q_.size == 32
    meas = m.measure(grey[1], Estimate(boxes[0]))
    assert np.hypot(*(meas.box.center - boxes[1].center)) < 4.0
