"""Small image helpers shared by the measurers: grey conversion and window cutting.

Image functions follow scikit-image's conventions: the image first,
keyword-only options, plain ndarrays out.
"""

from __future__ import annotations

import cv2
import numpy as np


def to_gray(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3) uint8`` BGR (or already grey) -> ``(H, W) float32`` grey."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return image.astype(np.float32)


def cut_window(image: np.ndarray, centre, size, out_size: tuple[int, int]) -> np.ndarray:
    """The ``size = (w, h)`` window of ``image`` centred on ``centre``, resampled to ``out_size = (w', h')``.

    Parts outside the image repeat its border (``cv2.BORDER_REPLICATE``);
    the window is resampled by :func:`resample`.  Works on ``(H, W)`` and
    ``(H, W, C)`` arrays.
    """
    w = max(int(round(size[0])), 1)
    h = max(int(round(size[1])), 1)
    x0 = int(round(centre[0] - w / 2.0))
    y0 = int(round(centre[1] - h / 2.0))
    H, W = image.shape[:2]
    cx0, cy0 = min(max(x0, 0), W - 1), min(max(y0, 0), H - 1)
    cx1, cy1 = max(min(x0 + w, W), cx0 + 1), max(min(y0 + h, H), cy0 + 1)
    patch = image[cy0:cy1, cx0:cx1]
    top, left = cy0 - y0, cx0 - x0
    bottom, right = (y0 + h) - cy1, (x0 + w) - cx1
    if top > 0 or left > 0 or bottom > 0 or right > 0:
        patch = cv2.copyMakeBorder(patch, max(top, 0), max(bottom, 0), max(left, 0), max(right, 0),
                                   cv2.BORDER_REPLICATE)
        patch = patch[max(-top, 0):patch.shape[0] - max(-bottom, 0), max(-left, 0):patch.shape[1] - max(-right, 0)]
    return resample(patch, out_size)


def resample(image: np.ndarray, out_size: tuple[int, int]) -> np.ndarray:
    """``image`` resampled to ``out_size = (w', h')``; shrinking approximates area averaging at a fraction of its cost.

    OpenCV's area averaging (``cv2.INTER_AREA``) is fast for a whole
    ratio and several times slower for a fractional one.  Here the whole
    part ``k = floor(min ratio)`` (when at least 2) is area-averaged on
    the integer path, after cropping the ``< k`` rows and columns it does
    not divide evenly from both sides (under half an output pixel); the
    remaining factor ``f`` per axis (below 2 on the axis of the smaller
    ratio) is a Gaussian pre-filter of the standard deviation of a box
    ``f`` pixels wide (``f / sqrt(12)``, the area average's own) followed
    by bilinear interpolation.  An axis that is enlarged is not filtered:
    bilinear interpolation alone.  Same size: the image itself (contiguous).
    """
    ow, oh = int(out_size[0]), int(out_size[1])
    fx, fy = image.shape[1] / ow, image.shape[0] / oh
    k = int(min(fx, fy))
    if k >= 2:
        h, w = image.shape[:2]
        cw, ch = (w // k) * k, (h // k) * k
        x0, y0 = (w - cw) // 2, (h - ch) // 2
        image = cv2.resize(image[y0:y0 + ch, x0:x0 + cw], (cw // k, ch // k), interpolation=cv2.INTER_AREA)
        fx, fy = image.shape[1] / ow, image.shape[0] / oh
    if image.shape[1] == ow and image.shape[0] == oh:
        return np.ascontiguousarray(image)
    if fx > 1.0 or fy > 1.0:
        image = cv2.GaussianBlur(image, (0, 0), sigmaX=max(fx, 1.0) / np.sqrt(12.0),
                                 sigmaY=max(fy, 1.0) / np.sqrt(12.0))
    return cv2.resize(image, (ow, oh), interpolation=cv2.INTER_LINEAR)
