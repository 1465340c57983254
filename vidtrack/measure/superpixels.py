"""Superpixels of a search region, their descriptors and an additive-kernel feature map.

The measurement components of *Multiple Instance Filtering* (Wnuk & Soatto)
are the SLIC superpixels of a search region around the filter's prediction.
Each superpixel gets a descriptor (colour histograms plus a texture cue),
mapped through an explicit feature map of the chi-squared additive kernel
(Vedaldi & Zisserman, *Efficient additive kernels via explicit feature maps*)
so that a linear SVM on the mapped features approximates a chi-squared SVM.

Everything here is a pure function of arrays; descriptors, label
statistics and adjacency are computed for all superpixels in one compiled
pass over the label image (Numba, without the GIL).

SLIC: the compiled implementation of :mod:`vidtrack.measure.slic` by
default, several times faster than OpenCV's ``ximgproc`` one on a search
region (which is kept as ``implementation="opencv"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from ..types import Box
from .slic import slic

#: Histogram bins per block of the descriptor.
LAB_BINS = (8, 6, 6)
ORIENTATION_BINS = 8
LBP_BINS = 10  # rotation-invariant uniform LBP(8, 1): 9 uniform codes + 1 "other"


@dataclass(frozen=True)
class Region:
    """A search region cut out of a frame and resampled.

    ``box`` is the region in frame pixels (integer-aligned, inside the
    frame); ``scale`` maps frame pixels to region pixels
    (``u = (x - box.x) * scale``); ``image`` ``(h, w, 3) uint8`` BGR.
    """

    box: Box
    scale: float
    image: np.ndarray

    def to_frame(self, u: np.ndarray | float, v: np.ndarray | float):
        """Region pixel coordinates -> frame coordinates."""
        return self.box.x + np.asarray(u) / self.scale, self.box.y + np.asarray(v) / self.scale

    def box_to_region(self, box: Box) -> Box:
        """A frame box expressed in region pixels."""
        return Box((box.x - self.box.x) * self.scale, (box.y - self.box.y) * self.scale,
                   box.w * self.scale, box.h * self.scale)


def search_box(center: np.ndarray, size: np.ndarray, extra: np.ndarray, *, pad: float = 0.6) -> Box:
    """The search region around a predicted box (Wnuk & Soatto, eq. 8).

    Half-extent per axis ``d/2 + pad * d + extra``; the caller passes
    ``extra = lam * sigma`` with ``sigma`` the prediction's centre standard
    deviation (``sqrt diag(C P C')``; the paper fixes ``lam = 3``), capped as
    it sees fit.  ``pad`` keeps a ring of background around the box for
    negatives even when the filter is certain.
    """
    half = np.asarray(size, float) * (0.5 + pad) + np.asarray(extra, float)
    c = np.asarray(center, float)
    return Box(float(c[0] - half[0]), float(c[1] - half[1]), float(2 * half[0]), float(2 * half[1]))


def cut_region(image: np.ndarray, box: Box, *, scale: float) -> Region | None:
    """Crop ``box`` (clipped to the image, integer-aligned) and resize by ``scale``.

    Parameters
    ----------
    image
        ``(H, W, 3) uint8`` BGR frame.
    box
        Wanted region in frame pixels.
    scale
        Resampling factor (<= 1 shrinks).

    Returns
    -------
    Region or None
        None when the clipped region is smaller than 8x8 pixels.
    """
    H, W = image.shape[:2]
    x0, y0 = int(np.floor(max(box.x, 0))), int(np.floor(max(box.y, 0)))
    x1, y1 = int(np.ceil(min(box.x + box.w, W))), int(np.ceil(min(box.y + box.h, H)))
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    crop = image[y0:y1, x0:x1]
    if scale != 1.0:
        w = max(8, int(round((x1 - x0) * scale)))
        h = max(8, int(round((y1 - y0) * scale)))
        crop = cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA)
        scale_x = w / (x1 - x0)
    else:
        crop = np.ascontiguousarray(crop)
        scale_x = 1.0
    return Region(Box(x0, y0, x1 - x0, y1 - y0), float(scale_x), crop)


def slic_labels(image: np.ndarray, *, region_size: int = 8, ruler: float = 10.0, iterations: int = 4,
                implementation: str = "numba") -> np.ndarray:
    """SLIC superpixels (Achanta et al.) of a BGR image, smoothed in Lab by a 3x3 Gaussian.

    Parameters
    ----------
    image
        ``(h, w, 3) uint8`` BGR.
    region_size
        Average superpixel side in pixels.
    ruler
        Compactness (larger: more square superpixels).
    iterations
        k-means iterations.
    implementation
        ``"numba"``: :func:`vidtrack.measure.slic.slic` (compiled, without
        the GIL, about 3x faster on a search region); ``"opencv"``: OpenCV's
        ``ximgproc`` SLIC.  The same algorithm with different seeding and
        merging details, so their superpixels differ slightly.

    Returns
    -------
    labels
        ``(h, w) int32`` labels ``0 .. K-1``, every label used.
    """
    lab = cv2.cvtColor(image, cv2.COLOR_BGR2Lab)
    lab = cv2.GaussianBlur(lab, (3, 3), 0)
    if implementation == "numba":
        return slic(lab, region_size=int(region_size), ruler=float(ruler), iterations=int(iterations))
    if implementation != "opencv":
        raise ValueError(f"unknown SLIC implementation {implementation!r}: 'numba' or 'opencv'")
    sp = cv2.ximgproc.createSuperpixelSLIC(lab, cv2.ximgproc.SLIC, int(region_size), float(ruler))
    sp.iterate(int(iterations))
    sp.enforceLabelConnectivity(25)
    labels = sp.getLabels()
    # compact the label set (connectivity enforcement may leave gaps): a lookup table, not np.unique's sort
    used = np.bincount(labels.ravel()) > 0
    compact = (np.cumsum(used) - 1).astype(np.int32)
    return compact[labels]


def _riu2_table() -> np.ndarray:
    """Rotation-invariant uniform code (``0 .. 9``) of each 8-bit LBP pattern: its number of ones if it has
    at most two 0/1 transitions around the circle, else 9."""
    codes = np.arange(256)
    bits = (codes[:, None] >> np.arange(8)) & 1
    transitions = np.sum(bits != np.roll(bits, 1, axis=1), axis=1)
    return np.where(transitions <= 2, bits.sum(axis=1), 9).astype(np.int64)


_RIU2 = _riu2_table()


def superpixel_descriptors(image: np.ndarray, labels: np.ndarray, n_labels: int | None = None) -> np.ndarray:
    """Per-superpixel descriptor: Lab colour histograms plus texture histograms.

    Blocks (each L1-normalised, so each is a distribution):
    marginal L, a, b histograms (``LAB_BINS``); gradient-orientation histogram
    weighted by gradient magnitude (``ORIENTATION_BINS``, the texture cue
    that still works on grey sequences); rotation-invariant uniform LBP
    histogram (``LBP_BINS``); and a 2-bin gradient-energy block
    ``[e, 1 - e]`` with ``e`` the mean gradient magnitude squashed to [0, 1].

    Parameters
    ----------
    image
        ``(h, w, 3) uint8`` BGR.
    labels
        ``(h, w) int`` superpixel labels ``0 .. K-1``.

    Returns
    -------
    descriptors
        ``(K, D) float64`` with ``D = sum(LAB_BINS) + ORIENTATION_BINS + LBP_BINS + 2``,
        every entry in [0, 1].
    """
    K = int(labels.max()) + 1 if n_labels is None else int(n_labels)
    lab = cv2.cvtColor(image, cv2.COLOR_BGR2Lab)
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3)
    mag, ang = cv2.cartToPolar(gx, gy)
    return _descriptor_histograms(lab, grey, mag, ang, np.ascontiguousarray(labels, dtype=np.int32), K, _RIU2,
                                  np.array(LAB_BINS, np.int64), ORIENTATION_BINS, LBP_BINS)


@numba.njit(cache=True, nogil=True)
def _descriptor_histograms(lab, grey, mag, ang, labels, K, riu2, lab_bins, orientation_bins, lbp_bins):
    """The blocks of :func:`superpixel_descriptors` in one pass over the pixels (compiled, no GIL)."""
    h, w = labels.shape
    n_lab = lab_bins[0] + lab_bins[1] + lab_bins[2]
    o_start = n_lab
    l_start = o_start + orientation_bins
    D = l_start + lbp_bins + 2
    out = np.zeros((K, D))
    area = np.zeros(K)
    energy = np.zeros(K)
    two_pi = 2.0 * np.pi
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            area[k] += 1.0
            start = 0
            for c in range(3):                               # marginal L, a, b histograms
                out[k, start + ((np.int64(lab[y, x, c]) * lab_bins[c]) >> 8)] += 1.0
                start += lab_bins[c]
            m = np.float64(mag[y, x])                       # magnitude-weighted orientation histogram
            ob = min(int(np.float64(ang[y, x]) * (orientation_bins / two_pi)), orientation_bins - 1)
            out[k, o_start + ob] += m
            energy[k] += m
            centre = grey[y, x]                             # LBP(8, 1), borders replicated
            pattern = 0
            bit = 0
            for dy, dx in ((-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1)):
                yy = min(max(y + dy, 0), h - 1)
                xx = min(max(x + dx, 0), w - 1)
                if grey[yy, xx] >= centre:
                    pattern |= 1 << bit
                bit += 1
            out[k, l_start + riu2[pattern]] += 1.0
    for k in range(K):
        a = max(area[k], 1.0)
        for j in range(n_lab):
            out[k, j] /= a
        total = 0.0
        for j in range(o_start, l_start):
            total += out[k, j]
        for j in range(o_start, l_start):
            out[k, j] = out[k, j] / total if total > 1e-9 else 1.0 / orientation_bins
        for j in range(l_start, l_start + lbp_bins):
            out[k, j] /= a
        e = energy[k] / a
        e = e / (e + 60.0)  # Sobel magnitude of a strong edge is a few hundred
        out[k, D - 2] = e
        out[k, D - 1] = 1.0 - e
    return out


def chi2_feature_map(X: np.ndarray, *, order: int = 1, period: float = 0.6) -> np.ndarray:
    """Explicit feature map of the additive chi-squared kernel (Vedaldi & Zisserman 2010).

    For ``k(x, y) = 2 x y / (x + y)`` with spectrum ``kappa(l) = sech(pi l)``,
    each non-negative entry ``x`` maps to ``2 order + 1`` features::

        sqrt(x L kappa(0)),
        sqrt(2 x L kappa(n L)) cos(n L log x),  sqrt(2 x L kappa(n L)) sin(n L log x),  n = 1..order

    so that ``<Psi(x), Psi(y)>`` approximates ``sum_i k(x_i, y_i)``.

    Parameters
    ----------
    X
        ``(K, D)`` non-negative descriptors.
    order, period
        Number of frequencies ``n`` and sampling period ``L``.

    Returns
    -------
    ``(K, D (2 order + 1))`` float64.
    """
    X = np.asarray(X, dtype=float)
    safe = np.maximum(X, 1e-12)
    log_x = np.log(safe)
    out = [np.sqrt(X * period)]  # kappa(0) = sech(0) = 1
    for n in range(1, order + 1):
        amp = np.sqrt(2.0 * X * period / np.cosh(np.pi * n * period))
        out.append(amp * np.cos(n * period * log_x))
        out.append(amp * np.sin(n * period * log_x))
    return np.concatenate(out, axis=1)


def label_stats(labels: np.ndarray, n_labels: int | None = None):
    """Area ``(K,)``, centroid ``(K, 2)`` ``[u, v]`` of every superpixel (region pixels)."""
    K = int(labels.max()) + 1 if n_labels is None else int(n_labels)
    return _label_stats(np.ascontiguousarray(labels), K)


@numba.njit(cache=True, nogil=True)
def _label_stats(labels, K):
    area = np.zeros(K)
    sums = np.zeros((K, 2))
    h, w = labels.shape
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            area[k] += 1.0
            sums[k, 0] += x
            sums[k, 1] += y
    centroid = np.empty((K, 2))
    for k in range(K):
        a = max(area[k], 1.0)
        centroid[k, 0] = sums[k, 0] / a
        centroid[k, 1] = sums[k, 1] / a
    return area, centroid


def fraction_inside(labels: np.ndarray, box: Box, n_labels: int | None = None) -> np.ndarray:
    """Fraction of each superpixel's area inside ``box`` (region pixels), ``(K,)``."""
    K = int(labels.max()) + 1 if n_labels is None else int(n_labels)
    h, w = labels.shape
    x0, y0 = int(round(max(box.x, 0))), int(round(max(box.y, 0)))
    x1, y1 = int(round(min(box.x + box.w, w))), int(round(min(box.y + box.h, h)))
    area = np.maximum(np.bincount(labels.ravel(), minlength=K), 1)
    if x1 <= x0 or y1 <= y0:
        return np.zeros(K)
    inside = np.bincount(labels[y0:y1, x0:x1].ravel(), minlength=K)
    return inside / area


def adjacency(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of 4-adjacent superpixels and their shared boundary length.

    Returns
    -------
    pairs
        ``(E, 2) int`` with ``pairs[:, 0] < pairs[:, 1]``, in increasing order of ``(first, second)``.
    lengths
        ``(E,)`` number of adjacent pixel pairs across each boundary.
    """
    return _adjacency(np.ascontiguousarray(labels), int(labels.max()) + 1)


@numba.njit(cache=True, nogil=True)
def _adjacency(labels, K):
    counts = np.zeros((K, K), np.int64)   # K is a few hundred at most: a K x K table beats a sort
    h, w = labels.shape
    for y in range(h):
        for x in range(w):
            a = labels[y, x]
            if x + 1 < w and labels[y, x + 1] != a:
                b = labels[y, x + 1]
                counts[min(a, b), max(a, b)] += 1
            if y + 1 < h and labels[y + 1, x] != a:
                b = labels[y + 1, x]
                counts[min(a, b), max(a, b)] += 1
    E = 0
    for i in range(K):
        for j in range(i + 1, K):
            if counts[i, j] > 0:
                E += 1
    pairs = np.empty((E, 2), np.int64)
    lengths = np.empty(E)
    e = 0
    for i in range(K):
        for j in range(i + 1, K):
            if counts[i, j] > 0:
                pairs[e, 0], pairs[e, 1], lengths[e] = i, j, counts[i, j]
                e += 1
    return pairs, lengths


# Load the compiled kernels at import, not inside the first tracked frame (see vidtrack.measure.slic).
_labels = np.zeros((8, 8), np.int32)
_labels[:, 4:] = 1
superpixel_descriptors(np.zeros((8, 8, 3), np.uint8), _labels)
label_stats(_labels)
adjacency(_labels)
del _labels
