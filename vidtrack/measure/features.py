"""Dense cell features for correlation filters: gradient-orientation histograms (HOG) and Lab colour.

The features of the correlation-filter detector (:mod:`vidtrack.measure.correlation`)
are computed per ``cell x cell`` pixel cell of a window, as in the HOG
variants that KCF and DSST use (Dalal & Triggs, "Histograms of Oriented
Gradients for Human Detection"):

* ``bins`` unsigned gradient-orientation channels: each pixel's gradient
  magnitude is split linearly between its two nearest orientation bins and
  summed over the cell; each cell's histogram is divided by the L2 energy of
  the 2x2-cell blocks around it and clipped at ``clip`` (HOG's block
  normalisation, averaged over the four blocks containing the cell);
* three Lab colour channels of each cell's mean colour (``L - 50``, ``a``,
  ``b``, divided by 100: about ``[-0.5, 0.5]``) (grey sequences give zero
  ``a``/``b``: the detector then runs on gradients and brightness only).

Everything is vectorised with OpenCV (Sobel, area resize, box filter), so a
128x128 window costs well under a millisecond.
"""

from __future__ import annotations

import cv2
import numba
import numpy as np

#: Default number of unsigned orientation bins.
ORIENTATION_BINS = 9


@numba.njit(cache=True, nogil=True)
def _orientation_histograms(mag: np.ndarray, angle: np.ndarray, cell: int, bins: int) -> np.ndarray:
    """Per-cell histograms ``(H / cell, W / cell, bins)`` of unsigned gradient orientation, magnitude-weighted.

    Each pixel's magnitude is split linearly between the two orientation
    bins nearest its angle (``[0, 2 pi)``, taken modulo ``pi``), bin centres
    at ``(k + 1/2) pi / bins``; pixels past the last whole cell go to the
    last one.  Compiled (no GIL): it runs in the correlation filter's thread
    beside the superpixels.
    """
    H, W = mag.shape
    hc, wc = H // cell, W // cell
    out = np.zeros((hc, wc, bins), np.float32)
    pi = np.float32(np.pi)
    scale = np.float32(bins / np.pi)
    column = np.empty(W, np.int64)
    for x in range(W):
        column[x] = min(x // cell, wc - 1)
    lows = np.empty(W, np.int64)
    fracs = np.empty(W, np.float32)
    for y in range(H):
        cells = out[min(y // cell, hc - 1)]
        m_row, a_row = mag[y], angle[y]
        for x in range(W):                               # the bins of a row first (a loop the compiler vectorises)
            a = a_row[x]
            if a >= pi:                                  # unsigned orientation in [0, pi)
                a -= pi
            pos = a * scale - np.float32(0.5)
            low = np.floor(pos)
            fracs[x] = pos - low
            lows[x] = np.int64(low)
        for x in range(W):                               # then the votes
            m = m_row[x]
            frac = fracs[x]
            lo = lows[x]
            hi = lo + 1
            if lo < 0:
                lo += bins
            if hi >= bins:
                hi -= bins
            c = column[x]
            cells[c, lo] += m - m * frac
            cells[c, hi] += m * frac
    return out


def orientation_cells(grey: np.ndarray, *, cell: int = 4, bins: int = ORIENTATION_BINS,
                      clip: float = 0.2) -> np.ndarray:
    """Block-normalised histograms of unsigned gradient orientation per cell.

    Parameters
    ----------
    grey : (H, W) float32
        ``H`` and ``W`` multiples of ``cell``.
    cell
        Cell side in pixels.
    bins
        Orientation bins over ``[0, pi)``.
    clip
        Clipping of the normalised histogram (HOG's 0.2).

    Returns
    -------
    (H / cell, W / cell, bins) float32
    """
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=1)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=1)
    mag, angle = cv2.cartToPolar(gx, gy)
    cells = _orientation_histograms(mag, angle, cell, bins)
    energy = np.sum(cells ** 2, axis=2)
    # energy of the 2x2 block whose top-left cell is (i, j), then the mean norm over the 4 blocks of a cell
    padded = cv2.copyMakeBorder(energy, 1, 1, 1, 1, cv2.BORDER_REPLICATE)   # np.pad's "edge", without its overhead
    block = padded[:-1, :-1] + padded[1:, :-1] + padded[:-1, 1:] + padded[1:, 1:]
    inv = 1.0 / np.sqrt(block + 1e-4)
    norm = 0.25 * (inv[:-1, :-1] + inv[1:, :-1] + inv[:-1, 1:] + inv[1:, 1:])
    return np.minimum(cells * norm[:, :, None], clip).astype(np.float32)


def colour_cells(image: np.ndarray, *, cell: int = 4) -> np.ndarray:
    """Lab colour of each cell's mean BGR colour, centred and scaled to about ``[-0.5, 0.5]``.

    Parameters
    ----------
    image : (H, W, 3) uint8 BGR or (H, W) uint8 grey

    Returns
    -------
    (H / cell, W / cell, 3) float32: ``L``, ``a``, ``b``.
    """
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    H, W = image.shape[:2]
    hc, wc = H // cell, W // cell
    means = cv2.resize(image[:hc * cell, :wc * cell], (wc, hc), interpolation=cv2.INTER_AREA)
    lab = cv2.cvtColor(means.astype(np.float32) / np.float32(255.0), cv2.COLOR_BGR2LAB)
    return ((lab - np.array([50.0, 0.0, 0.0], np.float32)) / np.float32(100.0)).astype(np.float32)


def cell_features(image: np.ndarray, *, cell: int = 4, bins: int = ORIENTATION_BINS,
                  colour: bool = True) -> np.ndarray:
    """HOG plus (optionally) Lab colour per cell: ``(H / cell, W / cell, bins + 3)`` float32.

    ``image`` is ``(H, W, 3) uint8`` BGR (or grey), ``H`` and ``W`` multiples of ``cell``.
    """
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    hog = orientation_cells(grey.astype(np.float32), cell=cell, bins=bins)
    if not colour:
        return hog
    return np.concatenate([hog, colour_cells(image, cell=cell)], axis=2)


# Load the compiled kernel at import, not inside the first tracked frame (see vidtrack.measure.slic).
orientation_cells(np.zeros((8, 8), np.float32))
