"""Channel Bayesian tracking filters on fixed channel grids: one axis, and a 2-D point from detections.

From Felsberg & Larsson, "Learning Object Tracking in Image Sequences" /
"Channel-Based Tracking".  The channel algebra (encoding, decoding, the
prediction ``w_{k|k-1} = F w_{k-1|k-1}`` and the update
``w_{k|k} = h(z_k) . w_{k|k-1} / h(z_k)' w_{k|k-1}`` of eq. 10, the
order-``n`` embedding) is in :mod:`vidtrack.channels`; this module adds

* :func:`product_likelihood` and :func:`mean_field_update` -- eq. 10 on a
  2-D position from unassociated detections, with one order-``n`` history
  tensor per axis: the prior of the current position is the product of the
  axes' marginals (mean field), the update with the 2-D likelihood is exact
  and its result is re-factorised into the axes;
* :class:`ChannelBayesFilter` -- one scalar, any order, with a measurement
  matrix (Carlin's experiment, :mod:`vidtrack.experiments.cbt_carlin`);
* :class:`PlanarCBT` -- a 2-D point on absolute channel grids from
  unassociated detections (:mod:`vidtrack.experiments.cbt_detections`).

The video filter on box centres is :class:`vidtrack.filters.cbt.CBTFilter`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..channels import (ChannelBasis, cbt_update, current_marginal, decode_nd, decode_nd_modes, embedded_predict,
                        encode, encode_nd, encode_samples, encode_unclipped, history_prior, normalized, shift_matrix)

_TINY = 1e-300


def product_likelihood(points, bases: Sequence[ChannelBasis], *, weights=None, clutter: float = 0.0,
                       H: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Likelihood ``h`` over a 2-D current-position channel grid from unassociated detections.

    ``h = clutter + sum_d s_d h_x(x_d) o h_y(y_d)`` where ``h_axis(z) = H_axis' c(z)``
    (identity ``H``: the detection's own encoding).  Detections outside the
    grid fade out instead of piling up on its border.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    h = np.full(tuple(b.n for b in bases), float(clutter))
    if len(points):
        s = np.ones(len(points)) if weights is None else np.asarray(weights, float)
        e = [encode_unclipped(points[:, d], b) for d, b in enumerate(bases)]
        if H is not None:
            e = [e_d @ H_d for e_d, H_d in zip(e, H)]
        h = h + np.einsum("m,mi,mj->ij", s, e[0], e[1])
    return h


def mean_field_update(Ws: Sequence[np.ndarray], h: np.ndarray, product: str = "plain") -> tuple[list[np.ndarray], np.ndarray, float]:
    """Eq. 10 on the 2-D current position with per-axis order-``n`` history tensors.

    The prior of the current position is the product of the axes' marginals;
    the update with the 2-D likelihood ``h`` is exact, and the result is
    re-factorised: each axis' history tensor is scaled by (new / old) marginal
    of its current position.  Returns the new tensors, the 2-D posterior
    (which keeps the cross-axis association of the detections, for decoding)
    and the evidence.
    """
    marg = [current_marginal(W) for W in Ws]
    joint = np.multiply.outer(marg[0], marg[1])
    post, evidence = cbt_update(joint, h, product)
    new = [post.sum(axis=1), post.sum(axis=0)]
    out = []
    for W, m, m_new in zip(Ws, marg, new):
        ratio = m_new / np.maximum(m, _TINY)
        out.append(normalized(W * ratio.reshape((-1,) + (1,) * (W.ndim - 1))))
    return out, post, evidence


class ChannelBayesFilter:
    """Channel Bayesian tracking of one scalar with an order-``n`` embedded model.

    Parameters
    ----------
    G
        Conditional tensor ``G[x_k, x_{k-1}, ..., x_{k-n}]`` (order ``n = G.ndim - 1``).
    H
        Measurement matrix ``(n_z, C)``: ``H[m, i]`` = channel ``m`` of ``p(z | x = channel i)``;
        the likelihood vector is ``h(z) = H' c(z)`` (eq. 10's ``h``).
    product
        ``"plain"`` or ``"sqrt"`` element-wise product in the update.
    """

    def __init__(self, G: np.ndarray, H: np.ndarray, *, product: str = "plain") -> None:
        self.G = np.asarray(G, dtype=float)
        self.H = np.asarray(H, dtype=float)
        self.product = product

    @property
    def order(self) -> int:
        return self.G.ndim - 1

    def initialize(self, W0: np.ndarray) -> None:
        """Start from the (empirical) prior tensor ``W[x_0, x_{-1}, ...]`` of shape ``(C,) * order``."""
        self.W_ = normalized(np.asarray(W0, dtype=float))

    def predict(self, shift_channels: float = 0.0) -> np.ndarray:
        """``W = F W``; optionally translate the new position by a known offset (in channels)."""
        W = embedded_predict(self.W_, self.G)
        if shift_channels:
            S = shift_matrix(W.shape[0], shift_channels)
            W = np.tensordot(S, W, axes=([1], [0]))
        self.W_ = W
        return W

    def likelihood(self, z_channels: np.ndarray) -> np.ndarray:
        """``h(z) = H' c(z)`` over the current position's channels."""
        return self.H.T @ z_channels

    def update(self, h: np.ndarray | None) -> float:
        """Fold in a likelihood vector over the current position (None: predict only)."""
        if h is None:
            return 1.0
        shape = (-1,) + (1,) * (self.order - 1)
        post, evidence = cbt_update(self.W_, np.broadcast_to(np.reshape(h, shape), self.W_.shape), self.product)
        self.W_ = post
        return evidence

    def marginal(self) -> np.ndarray:
        """Channel vector of the current position."""
        return current_marginal(self.W_)


class PlanarCBT:
    """CBT of a 2-D position with per-axis embedded models on fixed (absolute) channel grids.

    Parameters
    ----------
    bases
        ``(basis_x, basis_y)``.
    G
        Per-axis conditional tensors ``G[x_k, x_{k-1}, ..., x_{k-n}]``.
    H
        Per-axis measurement matrices ``(C, C)`` (None: identity).
    clutter
        Likelihood floor (drop-outs and clutter).
    product
        ``"plain"`` or ``"sqrt"``.
    """

    def __init__(self, bases, G, H=None, *, clutter: float = 0.01, product: str = "plain") -> None:
        self.bases = tuple(bases)
        self.G = [np.asarray(g, float) for g in G]
        self.H = None if H is None else [np.asarray(h, float) for h in H]
        self.clutter = clutter
        self.product = product

    @property
    def order(self) -> int:
        return self.G[0].ndim - 1

    def initialize_at(self, point) -> None:
        """Prior concentrated at ``point`` over the whole history."""
        self.W_ = [history_prior(encode(point[d], b), self.order) for d, b in enumerate(self.bases)]
        self.post_ = np.multiply.outer(encode(point[0], self.bases[0]), encode(point[1], self.bases[1]))

    def initialize_empirical(self, points, weights=None) -> None:
        """First-frame empirical prior: every detection of the first frame, over the whole history."""
        self.W_ = [history_prior(encode_samples(np.asarray(points)[:, d], b, weights), self.order)
                   for d, b in enumerate(self.bases)]
        self.post_ = encode_nd(points, self.bases, None if weights is None else normalized(np.asarray(weights, float)))

    def predict(self) -> None:
        self.W_ = [embedded_predict(W, G) for W, G in zip(self.W_, self.G)]
        m = [current_marginal(W) for W in self.W_]
        self.post_ = np.multiply.outer(m[0], m[1])

    def update(self, points, weights=None) -> float:
        h = product_likelihood(points, self.bases, weights=weights, clutter=self.clutter, H=self.H)
        self.W_, self.post_, evidence = mean_field_update(self.W_, h, self.product)
        return evidence

    def decode(self) -> tuple[np.ndarray, float]:
        """The strongest mode of the current position (frame units) and its mass."""
        t, mass = decode_nd(self.post_)
        return np.array([b.from_channel(v) for b, v in zip(self.bases, t)]), mass

    def modes(self, threshold: float = 0.1) -> list[tuple[np.ndarray, float]]:
        """Every mode holding at least ``threshold`` of the mass (multiple objects)."""
        return [(np.array([b.from_channel(v) for b, v in zip(self.bases, t)]), m)
                for t, m in decode_nd_modes(self.post_, threshold)]
