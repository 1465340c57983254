"""The correlation filter's samples summarised per frequency: their second moment and its regularised solve.

A multi-channel correlation filter learned over many samples ``x_j`` with
weights ``w_j`` (Danelljan et al., "ECO: Efficient Convolution Operators
for Tracking", eq. 3 with one desired output ``y``) has, per frequency, the
normal equations

    (sum_j w_j x_j x_j^H + c I) g = (sum_j w_j x_j) y + r,

a ``d x d`` Hermitian system for the ``d`` channels.  The samples enter only
through their weighted mean and their second moment ``S = sum_j w_j x_j
x_j^H``.  With the weights of a running average of rate ``eta``, ``S``
follows ``S <- (1 - eta) S + eta x x^H``, so every past sample counts,
faded, at the cost of one ``d x d`` matrix per frequency.  The average
sample alone (``S = x_bar x_bar^H``, rank one) is the cheaper model most
correlation trackers learn from; it forgets how the samples differ, and a
filter that fits the average can fit no single sample.

The kernels are compiled and release the GIL, so ``mil``'s second thread
solves while the first cuts superpixels.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, fastmath=True)
def accumulate_second_moment(moment: np.ndarray, sample: np.ndarray, rate: float) -> None:
    """``moment <- (1 - rate) moment + rate x x^H`` in place, per frequency (the lower triangle only).

    Parameters
    ----------
    moment : (h, w', d, d) complex128
        The running second moment; only ``moment[..., i, j]`` with ``j <= i`` is read and written.
    sample : (h, w', d) complex
        The new sample's spectrum ``x``.
    rate
        The running average's rate (1: the moment restarts from this sample).
    """
    rows, cols, d = sample.shape
    keep = 1.0 - rate
    for r in range(rows):
        for c in range(cols):
            for i in range(d):
                xi = sample[r, c, i] * rate
                for j in range(i + 1):
                    moment[r, c, i, j] = keep * moment[r, c, i, j] + xi * np.conj(sample[r, c, j])


@numba.njit(cache=True, nogil=True, fastmath=True)
def mean_trace(moment: np.ndarray) -> float:
    """The mean over frequencies of ``trace(moment)``: the samples' mean spectral energy."""
    rows, cols, d, _ = moment.shape
    total = 0.0
    for r in range(rows):
        for c in range(cols):
            for i in range(d):
                total += moment[r, c, i, i].real
    return total / (rows * cols)


@numba.njit(cache=True, nogil=True, fastmath=True)
def factor_regularised(moment: np.ndarray, ridge: float) -> np.ndarray:
    """Cholesky factors ``L`` with ``L L^H = moment + ridge I``, per frequency (lower triangles of ``moment``).

    ``ridge > 0`` keeps every system positive definite, however few samples
    the moment holds.
    """
    rows, cols, d, _ = moment.shape
    factor = np.zeros_like(moment)
    for r in range(rows):
        for c in range(cols):
            a = moment[r, c]
            low = factor[r, c]
            for i in range(d):
                for j in range(i + 1):
                    s = a[i, j] + (ridge if i == j else 0.0)
                    for k in range(j):
                        s -= low[i, k] * np.conj(low[j, k])
                    if i == j:
                        low[i, i] = np.sqrt(max(s.real, 1e-30))
                    else:
                        low[i, j] = s / low[j, j].real
    return factor


@numba.njit(cache=True, nogil=True, fastmath=True)
def solve_factored(factor: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``g`` with ``L L^H g = rhs`` per frequency, for the factors of :func:`factor_regularised`.

    Returns an array of ``rhs``'s shape ``(h, w', d)`` and dtype.
    """
    rows, cols, d = rhs.shape
    out = np.empty_like(rhs)
    z = np.empty(d, dtype=factor.dtype)
    for r in range(rows):
        for c in range(cols):
            low = factor[r, c]
            for i in range(d):            # forward: L z = rhs
                s = complex(rhs[r, c, i])
                for k in range(i):
                    s -= low[i, k] * z[k]
                z[i] = s / low[i, i].real
            for i in range(d - 1, -1, -1):  # backward: L^H g = z
                s = z[i]
                for k in range(i + 1, d):
                    s -= np.conj(low[k, i]) * z[k]
                z[i] = s / low[i, i].real
            for i in range(d):
                out[r, c, i] = z[i]
    return out
