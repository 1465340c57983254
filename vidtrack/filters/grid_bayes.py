"""Exact (grid) Bayes filter over a discrete state grid: pure steps and a thin class.

The posterior is a probability vector over grid points ``g_1..g_G``::

    p(x_k | z_{1:k-1}) = T p(x_{k-1} | z_{1:k-1})      (T[i, j] = P(g_i | g_j))
    p(x_k | z_{1:k})   ∝ p(z_k | g_i) p(x_k = g_i | z_{1:k-1})

(Arulampalam et al. 2002, section IV.A "grid-based methods").  Used as the
exact Bayes comparator of the NormalHedge paper (Gaussian random walk
transition) and as the approximate grid filter of the channel-based tracking
experiments.  Multi-dimensional grids are flattened; a separable transition
can be applied axis by axis with :func:`grid_predict_separable`.
"""

from __future__ import annotations

import numpy as np


def gaussian_transition(grid: np.ndarray, sigma: float, means: np.ndarray | None = None) -> np.ndarray:
    """``T[i, j] ∝ N(g_i; m_j, sigma^2)``, columns normalised over the grid.

    ``means`` defaults to ``grid`` (a random walk); pass ``f(grid)`` for a
    nonlinear transition ``x_k = f(x_{k-1}) + v``.
    """
    grid = np.asarray(grid, dtype=float)
    means = grid if means is None else np.asarray(means, dtype=float)
    T = np.exp(-0.5 * ((grid[:, None] - means[None, :]) / sigma) ** 2)
    col = T.sum(axis=0, keepdims=True)
    return T / np.where(col > 0, col, 1.0)


def grid_predict(p: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Prediction ``p' = T p`` (column-stochastic ``T``)."""
    return T @ p


def grid_predict_separable(p: np.ndarray, transitions: list[np.ndarray]) -> np.ndarray:
    """Prediction for a product grid ``p`` of shape ``(G_1, ..., G_d)`` with one transition per axis."""
    out = p
    for axis, T in enumerate(transitions):
        out = np.moveaxis(np.tensordot(T, out, axes=([1], [axis])), 0, axis)
    return out


def grid_update_log(p: np.ndarray, log_likelihood: np.ndarray) -> np.ndarray:
    """Update with a log-likelihood (numerically safe for sharp likelihoods)."""
    log_post = np.log(np.maximum(p, 1e-300)) + log_likelihood
    log_post -= log_post.max()
    post = np.exp(log_post)
    return post / post.sum()


class GridBayesFilter:
    """Grid Bayes filter over ``grid`` ``(G,)`` with a fixed column-stochastic transition ``T``."""

    def __init__(self, grid: np.ndarray, transition: np.ndarray) -> None:
        self.grid = np.asarray(grid, dtype=float)
        self.transition = np.asarray(transition, dtype=float)

    def initialize(self, prior: np.ndarray) -> None:
        self.p_ = np.asarray(prior, dtype=float) / np.sum(prior)

    def predict(self) -> np.ndarray:
        self.p_ = grid_predict(self.p_, self.transition)
        return self.p_

    def update_log(self, log_likelihood: np.ndarray) -> np.ndarray:
        self.p_ = grid_update_log(self.p_, log_likelihood)
        return self.p_

    def mean(self) -> float:
        return float(self.grid @ self.p_)
