"""The maths of discriminative correlation filters: pure functions on arrays.

The multi-channel linear correlation filter of the MOSSE/DSST family (Bolme
et al., "Visual Object Tracking using Adaptive Correlation Filters";
Danelljan et al., "Accurate Scale Estimation for Robust Visual Tracking").
For a window's features ``f_l`` (``l = 1..d`` channels, times a cosine
window) and a desired response ``g`` (a Gaussian peaked on the target), the
filter in the Fourier domain is (DSST eq. 4)::

    H_l = conj(G) F_l / (sum_k conj(F_k) F_k + lambda)

kept as a numerator ``A_l`` and denominator ``B`` that are running averages
over the frames it learns from (DSST eq. 5, learning rate ``eta``)::

    A_l <- (1 - eta) A_l + eta conj(G) F_l,    B <- (1 - eta) B + eta sum_k conj(F_k) F_k

and the response to a new window ``z`` is (DSST eq. 6)::

    y = IFFT( sum_l conj(A_l) Z_l / (B + lambda) )

:func:`constrained_filter` learns instead a filter that is zero outside the
target's cells by ADMM (Kiani Galoogahi et al., "Learning Background-Aware
Correlation Filters for Visual Tracking").  The quality of a response is its
peak-to-sidelobe ratio (Bolme et al.), :func:`peak_to_sidelobe`.

The stateful filters built on these are
:class:`~vidtrack.measure.correlation.CorrelationFilter` (translation) and
:class:`~vidtrack.measure.scale_filter.ScaleFilter` (DSST's scale filter).
"""

from __future__ import annotations

import numpy as np
from scipy import fft

from .sample_moments import factor_regularised, mean_trace, solve_factored


def gaussian_response(shape: tuple[int, int], sigma: float) -> np.ndarray:
    """The desired response: a Gaussian of ``sigma`` cells peaked at cell ``(0, 0)`` (circularly), ``(h, w)``."""
    h, w = shape
    dy = np.minimum(np.arange(h), h - np.arange(h))
    dx = np.minimum(np.arange(w), w - np.arange(w))
    return np.exp(-0.5 * (dy[:, None] ** 2 + dx[None, :] ** 2) / max(sigma, 1e-3) ** 2)


def cosine_window(shape: tuple[int, int]) -> np.ndarray:
    """Hann window ``(h, w)``, the cosine window that tapers a sample's borders."""
    return np.outer(np.hanning(shape[0] + 2)[1:-1], np.hanning(shape[1] + 2)[1:-1])


def dcf_terms(features_fft: np.ndarray, target_fft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numerator ``conj(G) F_l`` ``(h, w', d)`` and denominator ``sum_k |F_k|^2`` ``(h, w')`` of one sample (DSST eq. 4)."""
    numerator = np.conj(target_fft)[:, :, None] * features_fft
    denominator = np.sum(features_fft.real ** 2 + features_fft.imag ** 2, axis=2)
    return numerator, denominator


def running_average(old: tuple, new: tuple, rate: float) -> tuple:
    """DSST eq. 5 for each term: ``(1 - eta) old + eta new``; ``new`` itself when there is no ``old`` or ``eta >= 1``."""
    if old[0] is None or rate >= 1.0:
        return new
    return tuple((1.0 - rate) * a + rate * b for a, b in zip(old, new))


def correlation_response(filter_fft: np.ndarray, features_fft: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``y = IFFT(sum_l conj(H_l) Z_l)`` (DSST eq. 6 with ``H_l = A_l / (B + lambda)``), real ``(h, w)``, zero shift at ``(0, 0)``.

    ``filter_fft`` is DSST's ``A / (B + lambda)`` or :func:`constrained_filter`'s ``G``.
    """
    return fft.irfft2(np.sum(np.conj(filter_fft) * features_fft, axis=2), s=shape)


def constrained_filter(model_fft: np.ndarray, target_fft: np.ndarray, mask: np.ndarray, shape: tuple[int, int], *,
                       lam: float = 1e-2, iterations: int = 2, mu: float = 0.01, mu_step: float = 1.0,
                       mu_max: float = 1e4, start: tuple[np.ndarray, np.ndarray] | None = None,
                       moment: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A correlation filter that is zero outside ``mask``, learned by ADMM (Kiani Galoogahi et al., BACF, eqs. 5-13).

    Background-aware correlation filters train on every shift of the whole
    window, background included, but the filter itself covers only the
    target's cells (``mask``), so the static background a large window holds
    cannot outvote a small moving target.  The problem

        min_g 1/2 || y - sum_l conj(g_l) * x_l ||^2 + lam/2 || h ||^2   s.t.  g_l = FFT(mask * h_l)

    is solved by ADMM over the full-size filter ``g`` (closed form per
    frequency by Sherman-Morrison, since the model ``x`` is one sample:
    eq. 11), the masked filter ``h`` (eq. 12) and the Lagrange multiplier
    ``zeta`` (eq. 13), with penalty ``mu`` (relative to the model's mean
    spectral energy, so the result does not depend on the features' scale)
    multiplied by ``mu_step`` per iteration up to ``mu_max`` times its start.
    Departure from BACF, which restarts from zero every frame with a fast
    growing penalty: ADMM is warm-started from the previous frame's ``h``
    and ``zeta`` (``start``) at a constant penalty, so its few iterations a
    frame keep converging while the model drifts slowly.

    With ``moment``, the data term is every past sample's instead of the
    average sample's, ``sum_j w_j || y - sum_l conj(g_l) * x_{j,l} ||^2``
    (ECO's objective, Danelljan et al., eq. 3): the g-step solves
    ``(S + T mu I) g = x y + T mu h - T zeta`` per frequency with ``S`` the
    samples' second moment (:mod:`vidtrack.measure.sample_moments`), and the
    penalty is relative to the samples' mean energy ``mean(trace S)``.

    Parameters
    ----------
    model_fft : (h, w', d) complex
        ``rfft2`` of the (running-average) windowed features.
    target_fft : (h, w') complex
        ``rfft2`` of the desired response ``y``.
    mask : (h, w) bool or float
        Where the filter may be non-zero: the target's cells at the window's centre.
    shape
        ``(h, w)`` of the spatial window.
    start
        ``(h_fft, zeta)`` of a previous call to continue from (None: zeros).
    moment : (h, w', d, d) complex128, optional
        The samples' second moment (lower triangles), of which ``model_fft`` is the mean sample.

    Returns
    -------
    ``(G, h_fft, zeta)``, each (h, w', d) complex: ``G`` such that the
    response to ``z`` is ``irfft2(sum_l conj(G_l) Z_l)``, and the state to continue from.
    """
    T = float(shape[0] * shape[1])
    x = model_fft
    y = target_fft[:, :, None]
    s_xx = np.sum(x.real ** 2 + x.imag ** 2, axis=2, keepdims=True)
    energy = float(np.mean(s_xx)) if moment is None else mean_trace(moment)
    mu = mu * energy / T     # the penalty relative to the data's energy: scale-free
    mu_max = mu_max * mu
    g = np.zeros_like(x)
    h, zeta = (np.zeros_like(x), np.zeros_like(x)) if start is None else start
    m = mask.astype(np.float32)[:, :, None]
    x_conj = np.conj(x)
    yx, s_xx_y = y * x, s_xx * y
    terms_mu = None
    for _ in range(iterations):
        if moment is not None:
            if terms_mu != mu:
                factor = factor_regularised(moment, T * mu)
                terms_mu = mu
            g = solve_factored(factor, yx + (T * mu) * h - T * zeta)
        else:
            if terms_mu != mu:   # the terms that depend on the penalty alone, again only when it has grown
                b = s_xx + T * mu
                yx_mu, s_xx_y_mu = yx / (T * mu), s_xx_y / (T * mu)
                terms_mu = mu
            s_zx = np.sum(x_conj * zeta, axis=2, keepdims=True)
            s_hx = np.sum(x_conj * h, axis=2, keepdims=True)
            g = (yx_mu - zeta / mu + h
                 - x * (s_xx_y_mu - s_zx / mu + s_hx) / b)                                    # eq. 11
        spatial = fft.irfft2(mu * g + zeta, s=shape, axes=(0, 1)) * (T / (mu * T + lam))  # eq. 12
        h = fft.rfft2(spatial * m, axes=(0, 1))
        zeta = zeta + mu * (g - h)                                                           # eq. 13
        mu = min(mu_step * mu, mu_max)
    return g, h, zeta


def shift_cells(features: np.ndarray, shift) -> np.ndarray:
    """``features`` ``(h, w, d)`` moved by ``-shift = -(dx, dy)`` cells, circularly (sub-cell by the Fourier shift theorem).

    The result at cell ``p`` is the input at ``p + shift``: what sat ``shift``
    from the window centre comes to the centre.
    """
    h, w = features.shape[:2]
    spectrum = fft.rfft2(features, axes=(0, 1))
    fy = fft.fftfreq(h)[:, None]
    fx = fft.rfftfreq(w)[None, :]
    ramp = np.exp(2j * np.pi * (fy * float(shift[1]) + fx * float(shift[0]))).astype(np.complex64)
    return fft.irfft2(spectrum * ramp[:, :, None], s=(h, w), axes=(0, 1)).astype(np.float32)


def peak_to_sidelobe(response: np.ndarray, peak_index: tuple[int, int], exclude: int) -> float:
    """Peak-to-sidelobe ratio: ``(peak - mean) / std`` of the response outside ``exclude`` cells of the peak.

    ``response`` is circular (zero shift at ``(0, 0)``), so the excluded
    square wraps around the borders.
    """
    h, w = response.shape
    r, c = peak_index
    mask = np.ones((h, w), bool)
    rows = (np.arange(r - exclude, r + exclude + 1) % h)
    cols = (np.arange(c - exclude, c + exclude + 1) % w)
    mask[np.ix_(rows, cols)] = False
    side = response[mask]
    if side.size < 2:
        return 0.0
    return float((response[r, c] - side.mean()) / (side.std() + 1e-9))


def subpixel_peak(response: np.ndarray) -> tuple[np.ndarray, tuple[int, int], float]:
    """The circular response's peak: shift ``(dx, dy)`` in cells (sub-cell by parabolas), its index and value."""
    h, w = response.shape
    r, c = np.unravel_index(int(np.argmax(response)), response.shape)
    peak = float(response[r, c])

    def offset(a: float, b: float, cc: float) -> float:
        den = a - 2.0 * b + cc
        return 0.5 * (a - cc) / den if den < 0 else 0.0

    dr = offset(response[(r - 1) % h, c], peak, response[(r + 1) % h, c])
    dc = offset(response[r, (c - 1) % w], peak, response[r, (c + 1) % w])
    sy = r + dr if r <= h // 2 else r + dr - h     # circular index -> signed shift
    sx = c + dc if c <= w // 2 else c + dc - w
    return np.array([sx, sy], float), (int(r), int(c)), peak
