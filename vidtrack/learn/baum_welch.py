"""Learning Channel-Based Tracking models: covariance estimates and Baum-Welch on channel vectors.

From "Learning Object Tracking in Image Sequences" / "Channel-Based Tracking"
(Felsberg & Larsson).  Sequences are given as per-frame channel vectors
``c_k`` (``(T, C)`` arrays).  A frame's vector may encode one exactly known
state or a *set* of unassociated detections (the sum of their encodings:
clutter, drop-outs and displacements included) -- the correspondence-free
learning of section 3.4 uses the same code on such sets.

* :func:`covariance_transition` -- eq. 11 for any first-order channel state:
  ``F = sum_k w_k w_{k-1}' / (1 sum_k w_{k-1}')`` (columns normalised by the
  marginal of the previous state).
* :func:`embedded_covariance` -- the same estimate for the order-``n`` Markov
  model embedded in a first-order one (state = the last ``n`` positions), as
  the conditional tensor ``G[x_k, x_{k-1}, ..., x_{k-n}]`` of
  :mod:`vidtrack.channels`.
* :func:`measurement_matrix` -- the measurement model as a matrix from state
  channels to measurement channels, ``H[m, i]`` = channel ``m`` of
  ``p(z | x_i)``; the likelihood vector is ``h(z) = H' c(z)``.
* :func:`baum_welch` -- refinement of ``(G, H)`` from measurements alone:
  ``alpha_k = w_{k|k}`` (eq. 10), ``beta_k = F' (h(z_{k+1}) . beta_{k+1})``
  (eq. 17), ``F <- sum_k beta_{k+1} . h(z_{k+1}) . (F alpha_k) / N`` (eq. 18),
  ``h(z) <- sum_k z_k (alpha_k . beta_k) / N`` (eq. 19), with every product of
  two channel vectors optionally replaced by the square-root product.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..channels import channel_product, current_marginal, embedded_counts, embedded_predict, encode, normalized

_TINY = 1e-300
_LETTERS = "abcdefghij"


def covariance_transition(W_next: np.ndarray, W_prev: np.ndarray, *, eps: float = 1e-12) -> np.ndarray:
    """Eq. 11: ``F = sum_k w_k w_{k-1}' / (1 sum_k w_{k-1}')`` for ``(K, S)`` state channel vectors."""
    num = np.asarray(W_next, float).T @ np.asarray(W_prev, float)
    den = np.asarray(W_prev, float).sum(axis=0)[None, :]
    return num / np.maximum(den, eps)


def _history(seq: np.ndarray, order: int, k: int) -> np.ndarray:
    """Outer product ``c_k o c_{k-1} o ... o c_{k-order+1}``."""
    W = seq[k]
    for j in range(1, order):
        W = np.multiply.outer(W, seq[k - j])
    return W


def embedded_covariance(seqs: Sequence[np.ndarray], order: int, targets: Sequence[np.ndarray] | None = None,
                        *, floor: float = 1e-6) -> np.ndarray:
    """Eq. 11 in the embedded model: ``G = counts / marginal of the previous n positions``.

    ``counts`` is :func:`~vidtrack.channels.embedded_counts` of ``seqs``
    (and ``targets``).

    Histories never seen get a uniform column (``floor`` keeps every entry
    positive so a prediction never vanishes).
    """
    counts = embedded_counts(seqs, order, targets) + floor
    return counts / counts.sum(axis=0, keepdims=True)


def measurement_matrix(z_channels: np.ndarray, x_channels: np.ndarray, *, floor: float = 1e-6) -> np.ndarray:
    """``H[m, i] = sum_k z_k[m] x_k[i] / sum_k x_k[i]``: channels of ``p(z | x = channel i)``."""
    num = np.asarray(z_channels, float).T @ np.asarray(x_channels, float) + floor
    return num / num.sum(axis=0, keepdims=True)


def likelihoods(H: np.ndarray, z_channels: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """``h(z_k) = H' c(z_k)`` for every frame, ``(T, C)``; ``floor`` (fraction of each row's max) models drop-outs."""
    h = np.asarray(z_channels, float) @ H
    if floor > 0:
        h = h + floor * np.maximum(h.max(axis=1, keepdims=True), _TINY)
    return h


@dataclass
class BaumWelchResult:
    """Refined ``G``, ``H``, the per-iteration log-likelihood (``sum_k log`` of the update normalisers), the
    largest change of ``G`` per iteration, and the expected number of transitions out of each history in the
    last iteration (``history_mass``, the shape of ``G[0]``: how much data re-estimated each column)."""

    G: np.ndarray
    H: np.ndarray
    log_likelihood: list[float] = field(default_factory=list)
    change: list[float] = field(default_factory=list)
    history_mass: np.ndarray | None = None


def _broadcast_current(h: np.ndarray, order: int) -> np.ndarray:
    return h.reshape((-1,) + (1,) * (order - 1))


def _shift(W: np.ndarray, S: np.ndarray | None) -> np.ndarray:
    """Apply a known translation matrix to the current-position axis (identity when None)."""
    return W if S is None else np.tensordot(S, W, axes=([1], [0]))


def _unshift(E: np.ndarray, S: np.ndarray | None) -> np.ndarray:
    """The adjoint of :func:`_shift` (for the backward pass)."""
    return E if S is None else np.tensordot(S.T, E, axes=([1], [0]))


def forward(G: np.ndarray, h: np.ndarray, W0: np.ndarray, product: str = "plain",
            shifts: Sequence[np.ndarray | None] | None = None) -> tuple[list[np.ndarray], float]:
    """Alpha recursion: ``alpha_k = w_{k|k}`` (eq. 10) from the prior ``W0`` at frame ``order - 1``.

    ``h`` ``(T, C)`` likelihoods of the current position.  ``shifts[k]``, if
    given, is a known translation applied to the predicted position of frame
    ``k`` (Carlin's ``8 cos(1.2 k)``).  Returns the alphas for frames
    ``order - 1 .. T - 1`` and ``sum log`` of the normalisers.
    """
    order = G.ndim - 1
    alphas = [normalized(W0)]
    loglik = 0.0
    for k in range(order, len(h)):
        prior = normalized(_shift(embedded_predict(alphas[-1], G), None if shifts is None else shifts[k]))
        post = channel_product(_broadcast_current(h[k], order), prior, product)
        s = float(post.sum())
        loglik += np.log(max(s, _TINY))
        alphas.append(post / s if s > 0 else prior)
    return alphas, loglik


def backward(G: np.ndarray, h: np.ndarray, product: str = "plain",
             shifts: Sequence[np.ndarray | None] | None = None) -> list[np.ndarray]:
    """Beta recursion (eq. 17): ``beta_k = F' (h(z_{k+1}) . beta_{k+1})``, normalised, for frames ``order-1 .. T-1``."""
    order = G.ndim - 1
    letters = _LETTERS[: order + 1]
    shape = (G.shape[0],) * order
    betas = [np.full(shape, 1.0 / np.prod(shape))]
    for k in range(len(h) - 2, order - 2, -1):
        e = channel_product(_broadcast_current(h[k + 1], order), betas[-1], product)  # over x_{k+1}, ..., x_{k-n+2}
        e = _unshift(e, None if shifts is None else shifts[k + 1])
        # beta_k[x_k..x_{k-n+1}] = sum_{x_{k+1}} G[x_{k+1}, x_k, .., x_{k-n+1}] e[x_{k+1}, x_k, .., x_{k-n+2}]
        b = np.einsum(f"{letters},{letters[:-1]}->{letters[1:]}", G, e)
        betas.append(normalized(b))
    return betas[::-1]


def baum_welch(z_channels: Sequence[np.ndarray], G: np.ndarray, H: np.ndarray, *, iterations: int = 4,
               product: str = "plain", h_floor: float = 0.0, learn_H: bool = True, W0: Sequence[np.ndarray] | None = None,
               tol: float = 1e-4, smoothing: float = 1e-6,
               shifts: Sequence[Sequence[np.ndarray | None]] | None = None,
               prior_weight: float = 0.0) -> BaumWelchResult:
    """Refine an embedded model ``(G, H)`` from measurement channel sequences (eqs. 17-19).

    Parameters
    ----------
    z_channels
        Per sequence, ``(T, C_z)`` measurement channel vectors (a set of
        unassociated detections is the sum of their encodings).
    G
        Initial conditional ``G[x_k, x_{k-1}, ..., x_{k-n}]`` (the covariance estimate).
    H
        Initial measurement matrix ``(C_z, C)``.
    iterations
        Maximum number of EM iterations (the paper converged after four).
    product
        ``"plain"`` or ``"sqrt"`` (square-root products for channel vectors).
    h_floor
        Likelihood floor (fraction of each frame's maximum) for drop-outs.
    learn_H
        Also update ``H`` (eq. 19).
    W0
        Per sequence, the prior tensor at frame ``n - 1``; by default the
        empirical one, the outer product of the first ``n`` frames' vectors
        mapped to state channels.
    tol
        Stop when the largest change of ``G`` falls below this.
    shifts
        Per sequence and frame, an optional known translation matrix applied
        to the predicted position (``G`` then models the position before it).
    prior_weight
        MAP re-estimation with the initial ``G`` as a Dirichlet prior:
        ``G <- (xi_sum + prior_weight * G_init) / column sums``, i.e. every
        history column keeps ``prior_weight`` pseudo-frames of the initial
        model (0: maximum likelihood, eq. 18).  Histories the posterior never
        visits then keep the initial estimate instead of becoming uniform.

    Returns
    -------
    BaumWelchResult
    """
    G = np.asarray(G, float).copy()
    H = np.asarray(H, float).copy()
    order = G.ndim - 1
    result = BaumWelchResult(G, H)
    G_init = G.copy()
    for _ in range(iterations):
        xi_sum = np.zeros_like(G)
        gz_num = np.zeros_like(H)
        loglik = 0.0
        for s, z in enumerate(z_channels):
            z = np.asarray(z, float)
            if len(z) <= order:
                continue
            sh = None if shifts is None else shifts[s]
            h = likelihoods(H, z, h_floor)
            if W0 is not None:
                w0 = W0[s]
            else:
                # empirical prior from the first frames' likelihoods: c_{n-1} o c_{n-2} o ... o c_0
                w0 = _history(normalized_rows(h), order, order - 1)
            alphas, ll = forward(G, h, w0, product, sh)
            betas = backward(G, h, product, sh)
            loglik += ll
            for i in range(len(alphas) - 1):
                k = i + order - 1  # frame of alphas[i]
                e = channel_product(_broadcast_current(h[k + 1], order), betas[i + 1], product)
                e = _unshift(e, None if sh is None else sh[k + 1])
                # xi[x_{k+1}, x_k, ..., x_{k-n+1}] ∝ G . e[x_{k+1}, .., x_{k-n+2}] . alpha_k[x_k, .., x_{k-n+1}] (eq. 18)
                e_ext = e.reshape(e.shape + (1,))
                a_ext = alphas[i].reshape((1,) + alphas[i].shape)
                xi = G * channel_product(np.broadcast_to(e_ext, G.shape), np.broadcast_to(a_ext, G.shape), product)
                xi_sum += normalized(xi)
            if learn_H:
                for i, (a, b) in enumerate(zip(alphas, betas)):
                    k = i + order - 1
                    gamma = normalized(channel_product(a, b, product))  # alpha . beta
                    g = current_marginal(gamma)  # marginal of the current position
                    gz_num += np.outer(z[k], g)  # eq. 19: h(z) <- sum_k z_k (alpha_k . beta_k)
        result.history_mass = xi_sum.sum(axis=0)
        xi_sum += smoothing + prior_weight * G_init
        G_new = xi_sum / xi_sum.sum(axis=0, keepdims=True)
        change = float(np.max(np.abs(G_new - G)))
        G = G_new
        if learn_H:
            gz_num += smoothing
            H = gz_num / gz_num.sum(axis=0, keepdims=True)
        result.G, result.H = G, H
        result.log_likelihood.append(float(loglik))
        result.change.append(change)
        if change < tol:
            break
    return result


def normalized_rows(a: np.ndarray) -> np.ndarray:
    """Each row divided by its sum (rows summing to zero become uniform)."""
    a = np.asarray(a, float)
    s = a.sum(axis=1, keepdims=True)
    return np.where(s > 0, a / np.where(s > 0, s, 1.0), 1.0 / a.shape[1])


def embed_history(c_seq: np.ndarray, order: int, k: int) -> np.ndarray:
    """The order-``order`` state tensor of frame ``k`` from per-frame vectors: ``c_k o c_{k-1} o ...``."""
    return _history(np.asarray(c_seq, float), order, k)


def chain_counts(point_sets: Sequence[np.ndarray], bases, order: int, gate: float,
                 weights: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
    """Correspondence-free numerators of eq. 11 from sets of unassociated N-D detections, per axis.

    Every chain of detections ``(a_k, a_{k-1}, ..., a_{k-order})`` taken from
    consecutive frames whose consecutive links are shorter than ``gate``
    (Euclidean, all axes) adds ``c(a_k) o c(a_{k-1}) o ...`` to each axis'
    counts (weighted by the product of the detections' weights, and divided
    by the number of chains of the frame so a cluttered frame does not count
    more).  No association is given: true chains, chains through clutter and
    chains switching objects all count; the gate only encodes that an object
    moves less than ``gate`` per frame, which keeps the number of chains and
    the far cross-object background small.
    """
    counts = [np.zeros((b.n,) * (order + 1)) for b in bases]
    letters = _LETTERS[: order + 1]
    spec = ",".join(f"m{c}" for c in letters) + "->" + letters
    sets = [np.asarray(p, float).reshape(-1, len(bases)) for p in point_sets]
    wts = [np.ones(len(p)) if weights is None else np.asarray(w, float) for p, w in zip(sets, weights or sets)]
    enc = [[encode(p[:, d], b) for d, b in enumerate(bases)] for p in sets]
    for k in range(order, len(sets)):
        # chains as index tuples (i_k, i_{k-1}, ...), grown backwards through gated links
        chains = [(i,) for i in range(len(sets[k]))]
        for j in range(1, order + 1):
            prev = sets[k - j]
            grown = []
            for ch in chains:
                if len(prev) == 0:
                    continue
                d = np.linalg.norm(prev - sets[k - j + 1][ch[-1]], axis=1)
                grown.extend(ch + (int(i),) for i in np.flatnonzero(d < gate))
            chains = grown
        if not chains:
            continue
        idx = np.array(chains)
        w = np.ones(len(idx))
        for j in range(order + 1):
            w = w * wts[k - j][idx[:, j]]
        w = w / len(idx)
        for d in range(len(bases)):
            parts = [enc[k - j][d][idx[:, j]] for j in range(order + 1)]
            counts[d] += np.einsum("m," + spec, w, *parts)
    return counts
