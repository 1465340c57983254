"""SLIC superpixels compiled with Numba: the k-means and the connectivity pass run without the GIL.

Achanta et al., "SLIC Superpixels Compared to State-of-the-Art Superpixel
Methods" (TPAMI 2012), Algorithm 1: cluster centres ``C_k = [l, a, b, x, y]``
start on a regular grid of step ``S`` (each moved to the lowest-gradient
pixel of its 3x3 neighbourhood), and each iteration assigns every pixel of
the ``2S x 2S`` square around a centre to that centre when its distance

    D^2 = d_lab^2 + (m / S)^2 d_xy^2                                        (eq. 3)

is the smallest seen so far, then moves each centre to the mean of its
pixels.  A last pass (the paper's "enforce connectivity") relabels the
connected components in raster order and merges those smaller than
``min_size_percent`` % of ``S^2`` into the component they touch first.

This is :func:`vidtrack.measure.superpixels.slic_labels`' default
implementation.  OpenCV's ``ximgproc`` SLIC (the other one) spends about
0.5-0.7 ms an iteration on a 150x100 region and holds the interpreter
between its calls; this one is several times faster and releases the GIL,
so the correlation filter's thread runs beside it.  The two are the same
algorithm, not the same code: their superpixels differ in detail (seeding,
ties, the merge of small components).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _seeds(lab: np.ndarray, step: float) -> np.ndarray:
    """Grid centres ``(K, 5)`` ``[l, a, b, x, y]``, each moved to the lowest-gradient pixel of its 3x3 neighbourhood."""
    h, w = lab.shape[0], lab.shape[1]
    nx = max(int(w / step + 0.5), 1)
    ny = max(int(h / step + 0.5), 1)
    centres = np.empty((nx * ny, 5), np.float32)
    k = 0
    for j in range(ny):
        for i in range(nx):
            cx = int((i + 0.5) * w / nx)
            cy = int((j + 0.5) * h / ny)
            best = np.inf
            bx, by = cx, cy
            for y in range(max(cy - 1, 1), min(cy + 2, h - 1)):
                for x in range(max(cx - 1, 1), min(cx + 2, w - 1)):
                    g = 0.0
                    for c in range(3):   # G(x, y) = |I(x+1, y) - I(x-1, y)|^2 + |I(x, y+1) - I(x, y-1)|^2
                        dx = float(lab[y, x + 1, c]) - float(lab[y, x - 1, c])
                        dy = float(lab[y + 1, x, c]) - float(lab[y - 1, x, c])
                        g += dx * dx + dy * dy
                    if g < best:
                        best, bx, by = g, x, y
            for c in range(3):
                centres[k, c] = lab[by, bx, c]
            centres[k, 3] = bx
            centres[k, 4] = by
            k += 1
    return centres


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _kmeans(lab: np.ndarray, centres: np.ndarray, step: float, ruler: float, iterations: int) -> np.ndarray:
    """SLIC's local k-means (Algorithm 1): ``(h, w) int32`` nearest centre within ``step`` of each pixel."""
    h, w = lab.shape[0], lab.shape[1]
    K = centres.shape[0]
    labels = np.zeros((h, w), np.int32)
    dist = np.empty((h, w), np.float32)
    sums = np.empty((K, 6), np.float64)
    spatial = np.float32((ruler / step) ** 2)
    reach = int(step + 0.5)
    row_cost = np.empty(w, np.float32)
    L, A, B = lab[:, :, 0].copy(), lab[:, :, 1].copy(), lab[:, :, 2].copy()   # planes: unit-stride rows
    for _ in range(iterations):
        dist[:] = np.inf
        for k in range(K):
            cl, ca, cb, cx, cy = centres[k, 0], centres[k, 1], centres[k, 2], centres[k, 3], centres[k, 4]
            x0, x1 = max(int(cx) - reach, 0), min(int(cx) + reach + 1, w)
            y0, y1 = max(int(cy) - reach, 0), min(int(cy) + reach + 1, h)
            n = x1 - x0
            # rows as slices indexed from 0: the compiler sees non-negative indices and vectorises the loop
            dx2 = row_cost[:n]
            for i in range(n):
                dx = np.float32(x0 + i) - cx
                dx2[i] = spatial * dx * dx
            label = np.int32(k)
            for y in range(y0, y1):
                dy = np.float32(y) - cy
                dy2 = spatial * dy * dy
                l_row, a_row, b_row = L[y, x0:x1], A[y, x0:x1], B[y, x0:x1]
                dist_row, label_row = dist[y, x0:x1], labels[y, x0:x1]
                for i in range(n):
                    dl = l_row[i] - cl
                    da = a_row[i] - ca
                    db = b_row[i] - cb
                    d = dl * dl + da * da + db * db + dx2[i] + dy2   # eq. 3
                    better = d < dist_row[i]
                    dist_row[i] = d if better else dist_row[i]
                    label_row[i] = label if better else label_row[i]
        sums[:] = 0.0
        for y in range(h):
            for x in range(w):
                k = labels[y, x]
                sums[k, 0] += lab[y, x, 0]
                sums[k, 1] += lab[y, x, 1]
                sums[k, 2] += lab[y, x, 2]
                sums[k, 3] += x
                sums[k, 4] += y
                sums[k, 5] += 1.0
        for k in range(K):
            n = sums[k, 5]
            if n > 0:   # an empty cluster keeps its centre
                for c in range(5):
                    centres[k, c] = sums[k, c] / n
    return labels


@numba.njit(cache=True, nogil=True)
def _connected(labels: np.ndarray, min_size: int) -> np.ndarray:
    """Connected components of ``labels`` in raster order, those under ``min_size`` pixels merged into a neighbour.

    A small component takes the label of the component its first pixel
    touches on the left or above (already numbered); the first component
    of the image keeps its own label whatever its size.  Returns compact
    labels ``0 .. K-1``.
    """
    h, w = labels.shape
    out = np.full((h, w), -1, np.int32)
    queue_y = np.empty(h * w, np.int32)
    queue_x = np.empty(h * w, np.int32)
    count = 0
    for y0 in range(h):
        for x0 in range(w):
            if out[y0, x0] >= 0:
                continue
            adjacent = -1
            if x0 > 0:
                adjacent = out[y0, x0 - 1]
            elif y0 > 0:
                adjacent = out[y0 - 1, x0]
            old = labels[y0, x0]
            out[y0, x0] = count
            queue_y[0], queue_x[0] = y0, x0
            head, tail = 0, 1
            while head < tail:   # flood fill the 4-connected component
                y, x = queue_y[head], queue_x[head]
                head += 1
                for dy, dx in ((0, -1), (0, 1), (-1, 0), (1, 0)):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < w and out[yy, xx] < 0 and labels[yy, xx] == old:
                        out[yy, xx] = count
                        queue_y[tail], queue_x[tail] = yy, xx
                        tail += 1
            if tail < min_size and adjacent >= 0:
                for i in range(tail):
                    out[queue_y[i], queue_x[i]] = adjacent
            else:
                count += 1
    return out


def slic(lab: np.ndarray, *, region_size: int, ruler: float, iterations: int,
         min_size_percent: float = 25.0) -> np.ndarray:
    """SLIC superpixels of a Lab image (Achanta et al., Algorithm 1, and the connectivity pass).

    Parameters
    ----------
    lab : (h, w, 3) uint8 or float
        The image in CIELAB (OpenCV's 8-bit Lab scale), smoothed as the caller sees fit.
    region_size
        The grid step ``S``: about the superpixel side in pixels.
    ruler
        The compactness ``m`` of eq. 3 (in the Lab image's units).
    iterations
        k-means iterations.
    min_size_percent
        Components smaller than this percentage of ``S^2`` are merged into a neighbour.

    Returns
    -------
    (h, w) int32 labels ``0 .. K-1``, every label used, each a 4-connected region.
    """
    lab = np.ascontiguousarray(lab, dtype=np.float32)
    step = float(max(int(region_size), 1))
    return _slic(lab, step, float(ruler), int(iterations), int(step * step * min_size_percent / 100.0))


@numba.njit(cache=True, nogil=True)
def _slic(lab: np.ndarray, step: float, ruler: float, iterations: int, min_size: int) -> np.ndarray:
    """Seeds, k-means and the connectivity pass in one compiled call (one cached library to load)."""
    return _connected(_kmeans(lab, _seeds(lab, step), step, ruler, iterations), min_size)


# Load the compiled kernels now, at import (about 0.1-0.5 s from Numba's on-disk cache, seconds on
# the very first run when they are compiled), not inside the first frame a tracker processes.
slic(np.zeros((8, 8, 3), np.uint8), region_size=4, ruler=10.0, iterations=1)
