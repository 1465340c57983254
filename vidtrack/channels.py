"""Channel representations: cos² channel vectors, their decoding and the channel Bayesian steps.

From Felsberg & Larsson, "Learning Object Tracking in Image Sequences" and
"Channel-Based Tracking".  A density ``p(x)`` is represented by its channel
vector ``w_i = (p * b)(x_i)``, sampled with the cos² basis function (eq. 7/13)::

    b(x) = (2a/pi)^N prod_n cos²(a x_n)   if |x_n| < pi / (2a),  0 otherwise

on channel centres spaced ``pi / (3a)`` apart.  Working in *channel
coordinates* (centre ``j`` at ``t = j``, spacing 1) fixes ``a = pi/3``: every
value activates three channels and ``sum_j b(t - j) = 1`` for every ``t`` (the
1-D basis is a partition of unity), so encoding a sample gives a probability
vector.  Decoding (eq. 8/14) is the least-squares estimate inside the window of
three consecutive channels with the largest sum::

    x = l + 1/(2a) arg( sum_{j=l}^{l+2} w_j exp(i 2a (j - l)) )

(here evaluated around the window centre ``l + 1``, the same value without
phase wrapping).  N-D decoding marginalises locally inside the ``3^N`` window
of largest mass and decodes each marginal.

Tracking (eq. 10): ``w_{k|k-1} = F w_{k-1|k-1}`` and
``w_{k|k} = h(z_k) . w_{k|k-1} / h(z_k)' w_{k|k-1}``.  The higher-order
Markov model of order ``n`` is embedded into a first-order one whose state is
the joint of the last ``n`` positions, a tensor ``W[x_k, x_{k-1}, ...]``; its
transition is stored as the conditional tensor
``G[x_k, x_{k-1}, ..., x_{k-n}]`` (the embedded first-order ``F`` copies the
shared positions; :func:`embedded_matrix` builds it explicitly).  The
conditional is learned by the normalised covariance estimate (eq. 11,
:func:`embedded_counts`, :func:`conditional_from_counts`); a
translation-invariant displacement model in units of the box is mapped onto a
position grid by :func:`position_conditional`.

Products of channel vectors (the update, Baum-Welch) can be plain element-wise
products or *square-root products* ``sqrt(u . v)`` (the paper's replacement of
density products for channel vectors).  The section of the paper that defines
the square-root product is not in the text available to us; the geometric
mean is an assumption: it maps the encodings of two identical Dirac densities
to the same encoding instead of to a narrower cos⁴ kernel.

Pure functions on NumPy arrays only: the filters built on them
(:mod:`vidtrack.filters.channels`, :mod:`vidtrack.filters.cbt`) and the
learning of :mod:`vidtrack.learn.baum_welch` live above this module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.ndimage import maximum_filter, uniform_filter

#: ``a`` for unit channel spacing (spacing ``pi / (3a)`` = 1).
A_UNIT = np.pi / 3.0
_TINY = 1e-300


# --------------------------------------------------------------------- basis


@dataclass(frozen=True)
class ChannelBasis:
    """A 1-D channel layout: ``n`` cos² channels covering ``[lo, hi]``.

    Channel ``j`` is centred at ``lo + (j - 1) * spacing`` with
    ``spacing = (hi - lo) / (n - 3)``: ``lo`` sits on channel 1 and ``hi`` on
    channel ``n - 2``, so every value in ``[lo, hi]`` activates three channels
    and decodes exactly.
    """

    lo: float
    hi: float
    n: int

    def __post_init__(self) -> None:
        if self.n < 4 or not self.hi > self.lo:
            raise ValueError(f"ChannelBasis needs n >= 4 and hi > lo, got {self}")

    @property
    def spacing(self) -> float:
        return (self.hi - self.lo) / (self.n - 3)

    @property
    def centres(self) -> np.ndarray:
        return self.lo + (np.arange(self.n) - 1.0) * self.spacing

    def to_channel(self, x) -> np.ndarray:
        """Value(s) -> channel coordinate ``t`` (channel ``j`` at ``t = j``)."""
        return (np.asarray(x, dtype=float) - self.lo) / self.spacing + 1.0

    def from_channel(self, t) -> np.ndarray:
        """Channel coordinate -> value."""
        return self.lo + (np.asarray(t, dtype=float) - 1.0) * self.spacing

    @classmethod
    def with_spacing(cls, lo: float, hi: float, spacing: float) -> "ChannelBasis":
        """The smallest layout covering ``[lo, hi]`` with at most ``spacing`` between channels."""
        n = max(4, int(np.ceil((hi - lo) / spacing)) + 3)
        return cls(float(lo), float(lo + (n - 3) * spacing), n)


def cos2_kernel(t, a: float = A_UNIT) -> np.ndarray:
    """The 1-D cos² basis function ``b(t) = (2a/pi) cos²(a t)`` for ``|t| < pi/(2a)`` (eq. 7)."""
    t = np.asarray(t, dtype=float)
    return np.where(np.abs(t) < np.pi / (2 * a), (2 * a / np.pi) * np.cos(a * t) ** 2, 0.0)


def encode(x, basis: ChannelBasis) -> np.ndarray:
    """Channel vector(s) of value(s) ``x``: shape ``x.shape + (n,)``.

    Values outside the basis range are clipped to it first (a channel vector
    cannot represent them; clipping keeps the vector a probability vector).
    """
    t = np.clip(basis.to_channel(x), 1.0, basis.n - 2.0)
    return cos2_kernel(t[..., None] - np.arange(basis.n))


def encode_samples(x, basis: ChannelBasis, weights=None) -> np.ndarray:
    """Average channel vector of samples ``x`` ``(M,)``: the sampled Parzen estimate with kernel ``b``."""
    x = np.asarray(x, dtype=float).ravel()
    if x.size == 0:
        return np.zeros(basis.n)
    w = np.full(x.size, 1.0 / x.size) if weights is None else np.asarray(weights, float) / np.sum(weights)
    return w @ encode(x, basis)


def encode_nd(points, bases: Sequence[ChannelBasis], weights=None) -> np.ndarray:
    """Channel tensor ``(n_1, ..., n_N)`` of points ``(M, N)`` (N-D basis = product of 1-D ones, eq. 13).

    Each point contributes the outer product of its per-axis encodings, times
    its weight (default ``1/M``).  An empty set gives zeros.
    """
    points = np.asarray(points, dtype=float).reshape(-1, len(bases))
    shape = tuple(b.n for b in bases)
    if len(points) == 0:
        return np.zeros(shape)
    w = np.full(len(points), 1.0 / len(points)) if weights is None else np.asarray(weights, float)
    per_axis = [encode(points[:, d], b) for d, b in enumerate(bases)]
    letters = "abcdefgh"[: len(bases)]
    spec = "m," + ",".join(f"m{c}" for c in letters) + "->" + letters
    return np.einsum(spec, w, *per_axis)


def encode_density(pdf, basis: ChannelBasis, *, samples_per_channel: int = 64) -> np.ndarray:
    """Channel vector ``w_i = integral p(x) b(x - x_i) dx`` of a density callable ``pdf(x)`` (eq. 9/12).

    Integrated numerically (``samples_per_channel`` points per channel) over
    the basis range extended by 1.5 channels; the result sums to the mass the
    density puts in that range (the basis is a partition of unity).
    """
    t = np.linspace(-0.5, basis.n - 0.5, samples_per_channel * basis.n + 1)
    x = basis.from_channel(t)
    p = np.asarray(pdf(x), dtype=float)
    dx = x[1] - x[0]
    return (cos2_kernel(t[:, None] - np.arange(basis.n)) * p[:, None]).sum(axis=0) * dx



def encode_unclipped(x, basis: ChannelBasis) -> np.ndarray:
    """Like :func:`encode` but values beyond the range fade out to zero instead of being clipped."""
    t = basis.to_channel(x)
    return cos2_kernel(np.asarray(t)[..., None] - np.arange(basis.n))

# --------------------------------------------------------------------- decoding


def triplet_sums(w: np.ndarray) -> np.ndarray:
    """``s_l = w_l + w_{l+1} + w_{l+2}`` for ``l = 0 .. n-3``."""
    w = np.asarray(w, dtype=float)
    return w[:-2] + w[1:-1] + w[2:]


def decode_window(w: np.ndarray, first: int, a: float = A_UNIT) -> float:
    """Least-squares decoding (eq. 8/14) in the window ``l, l+1, l+2`` (``l = first``); channel coordinates."""
    window = np.asarray(w[first:first + 3], dtype=float)
    phase = np.angle(np.sum(window * np.exp(1j * 2 * a * (np.arange(3) - 1.0))))
    return float(first + 1 + phase / (2 * a))


def decode(w: np.ndarray, a: float = A_UNIT) -> tuple[float, float]:
    """Decode the strongest mode of a 1-D channel vector.

    Returns
    -------
    t : float
        The mode in channel coordinates (``basis.from_channel(t)`` for a value).
    mass : float
        The window's share of the total mass ``sum w``, in [0, 1].
    """
    w = np.maximum(np.asarray(w, dtype=float), 0.0)
    s = triplet_sums(w)
    first = int(np.argmax(s))  # l = argmax_j (w_j + w_{j+1} + w_{j+2})
    total = float(w.sum())
    return decode_window(w, first, a), (float(s[first]) / total if total > 0 else 0.0)


def decode_modes(w: np.ndarray, threshold: float = 0.1, a: float = A_UNIT) -> list[tuple[float, float]]:
    """Every mode whose triplet holds at least ``threshold`` of the mass, strongest first.

    Modes are local maxima of the triplet sums; windows closer than three
    channels to a stronger mode are suppressed.
    """
    w = np.maximum(np.asarray(w, dtype=float), 0.0)
    total = float(w.sum())
    if total <= 0:
        return []
    s = triplet_sums(w) / total
    order = np.argsort(-s, kind="stable")
    taken: list[int] = []
    modes = []
    for first in order:
        if s[first] < threshold:
            break
        if any(abs(int(first) - m) < 3 for m in taken):
            continue
        taken.append(int(first))
        modes.append((decode_window(w, int(first), a), float(s[first])))
    return modes


def _local_decode(W: np.ndarray, corner: tuple[int, ...], a: float) -> np.ndarray:
    window = W[tuple(slice(c, c + 3) for c in corner)]
    out = np.empty(W.ndim)
    for d in range(W.ndim):
        marginal = window.sum(axis=tuple(i for i in range(W.ndim) if i != d))
        out[d] = decode_window(marginal, 0, a) + corner[d]
    return out


def decode_nd(W: np.ndarray, a: float = A_UNIT) -> tuple[np.ndarray, float]:
    """Decode the strongest mode of an N-D channel tensor by local marginalisation.

    The ``3^N`` window of largest sum is found, marginalised to N 1-D triplets
    and each is decoded with eq. 8/14.  Returns the mode ``(N,)`` in channel
    coordinates and the window's share of the total mass.
    """
    W = np.maximum(np.asarray(W, dtype=float), 0.0)
    sums = _window_sums(W)
    corner = np.unravel_index(int(np.argmax(sums)), sums.shape)
    total = float(W.sum())
    return _local_decode(W, corner, a), (float(sums[corner]) / total if total > 0 else 0.0)


def _window_sums(W: np.ndarray) -> np.ndarray:
    """Sums over every ``3^N`` window; shape ``n_d - 2`` per axis, index = window corner."""
    box = uniform_filter(W, size=3, mode="constant", origin=-1) * 3 ** W.ndim
    return box[tuple(slice(0, s - 2) for s in W.shape)]


def decode_nd_modes(W: np.ndarray, threshold: float = 0.1, a: float = A_UNIT) -> list[tuple[np.ndarray, float]]:
    """Every mode of an N-D channel tensor holding at least ``threshold`` of the mass, strongest first."""
    W = np.maximum(np.asarray(W, dtype=float), 0.0)
    total = float(W.sum())
    if total <= 0:
        return []
    sums = _window_sums(W) / total
    peaks = (sums == maximum_filter(sums, size=5, mode="constant")) & (sums >= threshold)
    corners = np.argwhere(peaks)
    corners = corners[np.argsort(-sums[tuple(corners.T)], kind="stable")]
    modes: list[tuple[np.ndarray, float]] = []
    taken: list[np.ndarray] = []
    for c in corners:
        if any(np.max(np.abs(c - t)) < 3 for t in taken):
            continue
        taken.append(c)
        modes.append((_local_decode(W, tuple(int(v) for v in c), a), float(sums[tuple(c)])))
    return modes


# --------------------------------------------------------------------- tracking steps


def channel_product(u: np.ndarray, v: np.ndarray, product: str = "plain") -> np.ndarray:
    """Element-wise product of channel vectors: ``u . v`` or the square-root product ``sqrt(u . v)``."""
    if product == "plain":
        return u * v
    if product == "sqrt":
        return np.sqrt(np.maximum(u, 0.0) * np.maximum(v, 0.0))
    raise ValueError(f"product must be 'plain' or 'sqrt', got {product!r}")


def normalized(w: np.ndarray) -> np.ndarray:
    """``w / sum w`` (uniform when the sum vanishes)."""
    total = float(np.sum(w))
    if not np.isfinite(total) or total <= 0:
        return np.full(np.shape(w), 1.0 / np.size(w))
    return w / total


def current_marginal(W: np.ndarray) -> np.ndarray:
    """Channel vector of the current position: ``W[x_k, x_{k-1}, ...]`` summed over every history axis."""
    return W.reshape(W.shape[0], -1).sum(axis=1)


def cbt_predict(w: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Prediction ``w_{k|k-1} = F w_{k-1|k-1}`` (eq. 10), renormalised."""
    return normalized(F @ w)


def cbt_update(w_prior: np.ndarray, h: np.ndarray, product: str = "plain") -> tuple[np.ndarray, float]:
    """Update ``w_{k|k} = h(z_k) . w_{k|k-1} / h(z_k)' w_{k|k-1}`` (eq. 10).

    Returns the posterior and the evidence ``sum (h . w)``; when the evidence
    vanishes (nothing the prior allows was measured) the prior is kept.
    """
    post = channel_product(h, w_prior, product)
    evidence = float(post.sum())
    if not np.isfinite(evidence) or evidence <= 0:
        return w_prior, 0.0
    return post / evidence, evidence


def embedded_predict(W: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Prediction in the embedded first-order model of order ``n = W.ndim``.

    ``W[x_{k-1}, ..., x_{k-n}]`` -> ``W'[x_k, ..., x_{k-n+1}] =
    sum_{x_{k-n}} G[x_k, x_{k-1}, ..., x_{k-n}] W[x_{k-1}, ..., x_{k-n}]``:
    the first-order ``F`` of the embedding applied without building it.
    """
    n = W.ndim
    letters = "abcdefgh"[: n + 1]
    out = np.einsum(f"{letters},{letters[1:]}->{letters[:-1]}", G, W)
    return normalized(out)


def embedded_matrix(G: np.ndarray) -> np.ndarray:
    """The explicit first-order ``F`` ``(C^n, C^n)`` of the order-``n`` embedding with conditional ``G``.

    ``F[(i, j..), (j'.., m)] = delta(j.., j'..) G[i, j.., m]`` (C-order
    flattening); ``F @ W.ravel()`` equals ``embedded_predict(W, G).ravel()`` up
    to normalisation.
    """
    C = G.shape[0]
    n = G.ndim - 1
    F = np.zeros((C,) * (2 * n))
    for idx in np.ndindex(*(C,) * (n - 1)):
        # F[i, idx, idx, m] = G[i, idx, m]
        F[(slice(None),) + idx + idx + (slice(None),)] = G[(slice(None),) + idx + (slice(None),)]
    return F.reshape(C ** n, C ** n)


def history_prior(c: np.ndarray, order: int) -> np.ndarray:
    """``c`` repeated over the whole history of the embedded model: ``c ⊗ c ⊗ ... ⊗ c`` (``order`` factors).

    The first-frame prior of an order-``n`` state ``W[x_k, ..., x_{k-n+1}]``
    when only the current position's channel vector ``c`` is known.
    """
    W = c
    for _ in range(order - 1):
        W = np.multiply.outer(W, c)
    return W


def diagonal_history(m: np.ndarray, order: int) -> np.ndarray:
    """History tensor ``W[x_k, x_{k-1}, ...]`` with all positions equal, distributed as ``m`` (zero velocity)."""
    W = np.zeros((len(m),) * order)
    idx = np.arange(len(m))
    W[(idx,) * order] = m
    return normalized(W)


def shift_matrix(n: int, shift: float) -> np.ndarray:
    """Column-stochastic ``(n, n)`` matrix translating a channel vector by ``shift`` channels.

    Linear interpolation between the two integer shifts around ``shift``;
    mass pushed beyond the ends stays on the end channels.
    """
    lo = int(np.floor(shift))
    frac = shift - lo
    S = np.zeros((n, n))
    cols = np.arange(n)
    for offset, weight in ((lo, 1.0 - frac), (lo + 1, frac)):
        if weight == 0.0:
            continue
        rows = np.clip(cols + offset, 0, n - 1)
        np.add.at(S, (rows, cols), weight)
    return S


# --------------------------------------------------------------------- learned conditionals


def embedded_counts(seqs: Sequence[np.ndarray], order: int, targets: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Numerator of eq. 11 in the order-``order`` embedding: ``sum_k t_k o c_{k-1} o ... o c_{k-order}``.

    ``seqs`` are per-sequence ``(T, C)`` channel vectors ``c_k``; ``targets``
    (default ``seqs``) supplies the new-position vectors ``t_k``; give the
    vectors of a detrended variable (Carlin's ``x_k - 8 cos(1.2 k)``) to learn
    only the stationary part of the model.  Sequences of at most ``order``
    frames add nothing.  Shape ``(C_t,) + (C,) * order``.
    """
    targets = seqs if targets is None else targets
    C = np.asarray(seqs[0]).shape[1]
    counts = np.zeros((np.asarray(targets[0]).shape[1],) + (C,) * order)
    letters = "abcdefghij"[: order + 1]
    spec = ",".join(f"m{c}" for c in letters) + "->" + letters
    for seq, tgt in zip(seqs, targets):
        seq = np.asarray(seq, float)
        tgt = np.asarray(tgt, float)
        T = len(seq)
        if T <= order:
            continue
        parts = [tgt[order:T]] + [seq[order - j: T - j] for j in range(1, order + 1)]
        counts += np.einsum(spec, *parts)
    return counts


def displacement_counts(track: np.ndarray, basis: ChannelBasis, scale: float, order: int) -> np.ndarray:
    """Joint channel counts of ``order`` consecutive displacements of a 1-D track.

    ``d_k = (x_k - x_{k-1}) / scale``; returns ``sum_k c(d_k) o c(d_{k-1}) o ...``
    of shape ``(C,) * order`` (the numerator of the covariance estimate eq. 11
    for a translation-invariant model): :func:`embedded_counts` of the
    displacements' channel vectors with ``order - 1`` history positions.
    """
    d = np.diff(np.asarray(track, dtype=float)) / scale
    return embedded_counts([encode(d, basis)], order - 1)


def conditional_from_counts(counts: np.ndarray, prior: np.ndarray | None = None, prior_weight: float = 0.0) -> np.ndarray:
    """Normalised covariance (eq. 11): ``counts / marginal over the first axis``, regularised by a prior."""
    num = counts + (0.0 if prior is None else prior_weight * prior)
    den = counts.sum(axis=0, keepdims=True) + (0.0 if prior is None else prior_weight)
    return num / np.maximum(den, _TINY)


def random_walk_displacement(basis: ChannelBasis, sigma: float, order: int) -> np.ndarray:
    """Displacement conditional of a random walk: ``d_k ~ N(0, sigma²)`` whatever the history."""
    p = encode_density(lambda d: np.exp(-0.5 * (d / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi)), basis)
    p = normalized(p)
    return np.broadcast_to(p.reshape((-1,) + (1,) * (order - 1)), (basis.n,) * order).copy()


def position_conditional(D: np.ndarray, d_basis: ChannelBasis, pos_basis: ChannelBasis, scale: float) -> np.ndarray:
    """Conditional ``G[x_k, x_{k-1}, ..., x_{k-n}]`` on a position grid from a displacement model.

    ``D[d_k, d_{k-1}, ..., d_{k-n+1}]`` (``n = D.ndim``, displacements in units
    of ``scale``) is evaluated at the displacements between position channel
    centres; only the ``2C - 1`` distinct differences are encoded.  Columns
    are normalised over ``x_k``.
    """
    C = pos_basis.n
    n = D.ndim
    diffs = np.arange(-(C - 1), C) * pos_basis.spacing / scale
    E_next = encode_unclipped(diffs, d_basis)  # (2C-1, Cd): a jump beyond the model's range is impossible
    E_cond = encode(diffs, d_basis)  # a history beyond it conditions like the largest one modelled
    M = D
    for j in range(n):  # contract every displacement axis (each contraction appends its axis at the end)
        M = np.tensordot(M, E_next if j == 0 else E_cond, axes=([0], [1]))
    idx = np.ogrid[tuple(slice(0, C) for _ in range(n + 1))]  # open grids: no (n+1, C^(n+1)) index array
    keys = tuple(idx[j] - idx[j + 1] + C - 1 for j in range(n))
    G = M[keys]
    G += 1e-9
    G /= G.sum(axis=0, keepdims=True)
    return G


def shift_tensor(W: np.ndarray, shift: int) -> np.ndarray:
    """``W`` moved by ``shift`` whole channels towards lower indices along every axis, zeros shifted in.

    ``out[i, j, ...] = W[i + shift, j + shift, ...]``: the tensor of the same
    positions on a grid whose origin moved ``shift`` channels up.  Mass that
    leaves the grid is dropped (the result is not renormalised).
    """
    shift = int(shift)
    if shift == 0:
        return W
    out = np.zeros_like(W)
    C = W.shape[0]
    if abs(shift) >= C:
        return out
    src = slice(shift, C) if shift > 0 else slice(0, C + shift)
    dst = slice(0, C - shift) if shift > 0 else slice(-shift, C)
    out[(dst,) * W.ndim] = W[(src,) * W.ndim]
    return out
