"""A colour-histogram object model whose per-pixel score complements the correlation filter.

Staple (Bertinetto et al., "Staple: Complementary Learners for Real-Time
Tracking", CVPR 2016, sec. 4-5) pairs a correlation filter, which is
precise but relies on the target's rigid layout, with a model that ignores
layout: histograms of the colours of the object ``O`` and of the
background ``B`` around it.  Every pixel ``u`` with colour bin ``k(u)`` gets
the probability that it belongs to the object (Staple eq. 14)::

    beta(u) = rho_O(k) / (rho_O(k) + rho_B(k) + epsilon)

with ``rho_O``, ``rho_B`` the histograms normalised by the number of pixels
in each region, and the score of a box at position ``p`` is the mean of
``beta`` over the box (eq. 12, computed with a box filter, i.e. an integral
image).  The two responses are merged linearly (eq. 22)::

    y = (1 - alpha) y_cf + alpha y_hist

The histograms are running averages over the frames the tracker learns from
(learning rate ``eta_hist``, eq. 21).  Bins are joint over the three BGR
channels, ``bins`` levels each (Staple: 32).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numba
import numpy as np


@numba.njit(cache=True, nogil=True, error_model="numpy")   # IEEE division (no zero check): vectorised
def _update_histograms(index, obj, bg, object_hist, background_hist, table, rate):
    """Staple's running histograms in place (eq. 14's ``rho``), and the object-probability table.

    ``object_hist <- (1 - rate) object_hist + rate h_O`` with ``h_O`` the
    normalised histogram of ``index`` under ``obj`` (likewise the
    background), then ``table = object / (object + background + 1e-9)``.
    Compiled: one pass over the pixels, none of ``np.bincount``'s
    ``bins ** 3``-long temporaries, no GIL.
    """
    n = object_hist.shape[0]
    count_obj = np.zeros(n)
    count_bg = np.zeros(n)
    n_obj = 0
    n_bg = 0
    H, W = index.shape
    for y in range(H):
        for x in range(W):
            if obj[y, x]:
                count_obj[index[y, x]] += 1.0
                n_obj += 1
            if bg[y, x]:
                count_bg[index[y, x]] += 1.0
                n_bg += 1
    n_obj = max(n_obj, 1)
    n_bg = max(n_bg, 1)
    for i in range(n):
        object_hist[i] = (1.0 - rate) * object_hist[i] + rate * (count_obj[i] / n_obj)
        background_hist[i] = (1.0 - rate) * background_hist[i] + rate * (count_bg[i] / n_bg)
        table[i] = np.float32(object_hist[i] / (object_hist[i] + background_hist[i] + 1e-9))


def colour_bins(patch: np.ndarray, bins: int) -> np.ndarray:
    """Joint colour-bin index ``(H, W)`` int32 of a BGR (or grey) uint8 patch, ``bins`` levels per channel."""
    shift = int(round(np.log2(256 // bins)))
    if patch.ndim == 2:
        return (patch >> shift).astype(np.int32) * (bins * bins + bins + 1)   # grey: the diagonal of the colour cube
    return _joint_bins(np.ascontiguousarray(patch), shift, bins)


@numba.njit(cache=True, nogil=True)
def _joint_bins(patch, shift, bins):
    """``((b >> shift) bins + (g >> shift)) bins + (r >> shift)`` per pixel (compiled, no GIL)."""
    H, W = patch.shape[0], patch.shape[1]
    out = np.empty((H, W), np.int32)
    for y in range(H):
        for x in range(W):
            out[y, x] = ((np.int32(patch[y, x, 0] >> shift) * bins + np.int32(patch[y, x, 1] >> shift)) * bins
                         + np.int32(patch[y, x, 2] >> shift))
    return out


def box_masks(shape: tuple[int, int], box_size, *, inner: float = 0.1, context: float = 1.0,
              offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Object and background masks of a patch ``shape = (H, W)`` holding a box of ``box_size = (w, h)`` px.

    The box is centred ``offset = (dx, dy)`` px from the patch centre.  The
    object region is the box shrunk by ``inner`` of its side on each side
    (so its border pixels, often background, stay out); the background is
    the box grown by ``context`` of its side on each side, less the box.
    """
    H, W = shape
    cx, cy = W / 2.0 + float(offset[0]), H / 2.0 + float(offset[1])
    bw, bh = float(box_size[0]), float(box_size[1])

    def rect(w: float, h: float) -> np.ndarray:
        m = np.zeros((H, W), bool)
        x0, x1 = int(round(max(cx - w / 2.0, 0))), int(round(min(cx + w / 2.0, W)))
        y0, y1 = int(round(max(cy - h / 2.0, 0))), int(round(min(cy + h / 2.0, H)))
        m[y0:y1, x0:x1] = True
        return m

    obj = rect(bw * (1.0 - 2.0 * inner), bh * (1.0 - 2.0 * inner))
    bg = rect(bw * (1.0 + 2.0 * context), bh * (1.0 + 2.0 * context)) & ~rect(bw, bh)
    return obj, bg


@lru_cache(maxsize=8)
def _fixed_masks(shape: tuple[int, int], w: float, h: float, inner: float, context: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`box_masks`, cached (read-only): a tracker's patch shape and box size in patch pixels stay fixed."""
    masks = box_masks(shape, (w, h), inner=inner, context=context)
    for m in masks:
        m.setflags(write=False)
    return masks


@dataclass
class ColourHistogramModel:
    """Staple's object/background colour histograms; see the module docstring.

    Parameters
    ----------
    bins
        Levels per BGR channel (a power of two; the histograms have ``bins ** 3`` entries).
    learning_rate
        ``eta_hist`` of the running histograms.
    inner, context
        Shape of the object and background regions (:func:`box_masks`).
    """

    bins: int = 32
    learning_rate: float = 0.04
    inner: float = 0.1
    context: float = 1.0

    def __post_init__(self) -> None:
        self.object_ = self.background_ = None

    def update(self, patch: np.ndarray, box_size, *, rate: float | None = None, offset=None,
               index: np.ndarray | None = None) -> None:
        """Learn from a patch holding the target box of ``box_size`` patch pixels at its centre.

        ``offset = (dx, dy)``: the box is that many patch pixels from the
        centre instead (rounded to whole pixels); ``index``: the patch's
        :func:`colour_bins`, when already computed.
        """
        rate = self.learning_rate if rate is None else rate
        index = colour_bins(patch, self.bins) if index is None else index
        dx, dy = (0, 0) if offset is None else (int(round(offset[0])), int(round(offset[1])))
        if dx == 0 and dy == 0:
            obj, bg = _fixed_masks(index.shape, float(box_size[0]), float(box_size[1]), self.inner, self.context)
        else:
            obj, bg = box_masks(index.shape, box_size, inner=self.inner, context=self.context, offset=(dx, dy))
        if self.object_ is None or rate >= 1.0:   # the first sample: the histograms are its own
            self.object_ = np.zeros(self.bins ** 3)
            self.background_ = np.zeros(self.bins ** 3)
            self.table_ = np.empty(self.bins ** 3, np.float32)
            rate = 1.0
        _update_histograms(index, obj, bg, self.object_, self.background_, self.table_, float(rate))

    def likelihood(self, patch: np.ndarray, *, index: np.ndarray | None = None) -> np.ndarray:
        """``beta(u)``: the object probability of every pixel, ``(H, W)`` float32 (eq. 14)."""
        return self.table_[colour_bins(patch, self.bins) if index is None else index]

    def response(self, patch: np.ndarray, box_size, shape: tuple[int, int], step: float, *,
                 index: np.ndarray | None = None) -> np.ndarray:
        """Mean ``beta`` over the box at each of ``shape = (h, w)`` positions ``step`` px apart, centred (eq. 12).

        Position ``(i, j)`` is the box centred ``((j - w // 2) step, (i - h // 2) step)``
        from the patch centre: the layout of a shifted correlation response.
        ``index``: the patch's :func:`colour_bins`, when already computed.
        """
        k = (max(int(round(box_size[0])), 1), max(int(round(box_size[1])), 1))
        mean = cv2.boxFilter(self.likelihood(patch, index=index), -1, k, normalize=True, borderType=cv2.BORDER_REPLICATE)
        H, W = mean.shape
        h, w = shape
        rows = np.clip(np.round(H / 2.0 + (np.arange(h) - h // 2) * step).astype(int), 0, H - 1)
        cols = np.clip(np.round(W / 2.0 + (np.arange(w) - w // 2) * step).astype(int), 0, W - 1)
        return mean[np.ix_(rows, cols)]


# Load the compiled kernels at import, not inside the first tracked frame (see vidtrack.measure.slic).
_model = ColourHistogramModel(bins=4)
_model.update(np.zeros((8, 8, 3), np.uint8), (4, 4), rate=1.0)
del _model
