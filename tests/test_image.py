"""The measurers' resampling: :func:`vidtrack.measure.image.resample` and :func:`~vidtrack.measure.image.cut_window`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vidtrack.measure.image import cut_window, resample

FACTORS = (1.5, 2.5, 3.7, 6.3)


def _grid(h: int = 300, w: int = 400) -> tuple[np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[0:h, 0:w]
    return yy, xx


def _out_size(image: np.ndarray, factor: float) -> tuple[int, int]:
    return int(round(image.shape[1] / factor)), int(round(image.shape[0] / factor))


@pytest.mark.parametrize("factor", FACTORS)
def test_resample_matches_area_averaging_on_smooth_content(factor):
    yy, xx = _grid()
    smooth = (127 + 60 * np.sin(xx / 23.0) + 50 * np.cos(yy / 17.0)).astype(np.uint8)
    size = _out_size(smooth, factor)
    area = cv2.resize(smooth, size, interpolation=cv2.INTER_AREA).astype(float)
    ours = resample(smooth, size).astype(float)
    assert ours.shape == area.shape
    assert np.abs(ours - area)[2:-2, 2:-2].mean() < 2.5


@pytest.mark.parametrize("factor", FACTORS)
def test_resample_filters_what_it_cannot_represent(factor):
    """A one-pixel checkerboard shrunk comes out near its mean grey; plain bilinear sampling aliases it."""
    yy, xx = _grid()
    checker = (((xx + yy) % 2) * 255).astype(np.uint8)
    size = _out_size(checker, factor)
    bilinear = cv2.resize(checker, size, interpolation=cv2.INTER_LINEAR).astype(float)
    ours = resample(checker, size).astype(float)
    assert abs(ours.mean() - 127.5) < 5.0
    assert ours.std() < 0.6 * bilinear.std()


@pytest.mark.parametrize("factor", FACTORS)
def test_resample_keeps_positions(factor):
    """A small bright square lands where the scale maps it (pixel centres), within a quarter of an output pixel."""
    image = np.zeros((300, 400), np.uint8)
    image[140:150, 250:260] = 255
    size = _out_size(image, factor)
    out = resample(image, size).astype(float)
    ys, xs = np.mgrid[0:out.shape[0], 0:out.shape[1]]
    cx, cy = (out * xs).sum() / out.sum(), (out * ys).sum() / out.sum()
    sx, sy = 400 / size[0], 300 / size[1]
    assert cx == pytest.approx((254.5 + 0.5) / sx - 0.5, abs=0.25)
    assert cy == pytest.approx((144.5 + 0.5) / sy - 0.5, abs=0.25)


def test_resample_keeps_channels_and_type():
    image = np.random.default_rng(0).integers(0, 256, (90, 120, 3), dtype=np.uint8)
    out = resample(image, (37, 28))
    assert out.shape == (28, 37, 3) and out.dtype == np.uint8


def test_cut_window_resamples_with_resample():
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, (200, 300, 3), dtype=np.uint8)
    small = cut_window(image, (150.0, 100.0), (40, 30), (80, 60))
    assert np.array_equal(small, cv2.resize(image[85:115, 130:170], (80, 60), interpolation=cv2.INTER_LINEAR))
    large = cut_window(image, (150.0, 100.0), (160, 120), (50, 40))
    assert np.array_equal(large, resample(image[40:160, 70:230], (50, 40)))
