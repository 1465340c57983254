"""Sequential importance resampling (SIR) particle filter: pure steps and a thin class.

Model-agnostic (Gordon, Salmond & Smith 1993; Arulampalam et al., "A Tutorial
on Particle Filters for Online Nonlinear/Non-Gaussian Bayesian Tracking",
2002, Algorithm 4): particles are propagated by sampling the transition
density, weighted by the likelihood, and resampled when the effective sample
size falls below a fraction of ``N``.  Used by the NormalHedge comparison
(``pf`` on video and the 1-D experiment) and by the channel-based tracking
experiments.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.special import logsumexp

Propagate = Callable[[np.ndarray, np.random.Generator], np.ndarray]
LogLikelihood = Callable[[np.ndarray], np.ndarray]


def normalize_log_weights(log_w: np.ndarray) -> tuple[np.ndarray, float]:
    """``(w, log_sum)``: normalised weights from log weights, and ``log sum exp(log_w)``."""
    total = float(logsumexp(log_w))
    if not np.isfinite(total):  # every weight zero: fall back to uniform
        return np.full(len(log_w), 1.0 / len(log_w)), total
    return np.exp(log_w - total), total


def effective_sample_size(weights: np.ndarray) -> float:
    """``1 / sum w_i^2`` for normalised weights."""
    return float(1.0 / np.sum(np.square(weights)))


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices drawn by systematic resampling (one uniform offset, ``N`` even strata)."""
    n = len(weights)
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    return np.searchsorted(cumulative, positions)


def sir_step(particles: np.ndarray, weights: np.ndarray, propagate: Propagate, log_likelihood: LogLikelihood | None,
             rng: np.random.Generator, *, resample_below: float = 0.5) -> tuple[np.ndarray, np.ndarray, float]:
    """One SIR cycle.

    ``x_i ~ p(x_k | x_{k-1,i})`` (``propagate``); ``w_i ∝ w_i p(z_k | x_i)``
    (``log_likelihood``, None for predict only); resample when
    ``N_eff < resample_below * N``.

    Returns
    -------
    particles, weights : the new particle set (weights normalised)
    log_evidence : float, ``log sum_i w_i p(z | x_i)`` (0 when predicting only)
    """
    particles = propagate(particles, rng)
    log_evidence = 0.0
    if log_likelihood is not None:
        log_w = np.log(np.maximum(weights, 1e-300)) + log_likelihood(particles)
        weights, log_evidence = normalize_log_weights(log_w)
    if effective_sample_size(weights) < resample_below * len(weights):
        idx = systematic_resample(weights, rng)
        particles = particles[idx]
        weights = np.full(len(weights), 1.0 / len(weights))
    return particles, weights, log_evidence


def sir_step_batch(particles: np.ndarray, weights: np.ndarray, propagate: Propagate,
                   log_likelihood: LogLikelihood | None, rng: np.random.Generator, *,
                   resample_below: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`sir_step` on ``B`` independent particle sets at once.

    ``particles`` ``(B, N, ...)``, ``weights`` ``(B, N)``; ``propagate`` and
    ``log_likelihood`` act on the whole batch (``log_likelihood`` returns
    ``(B, N)``).  Each set is normalised and (when its ``N_eff`` is low)
    resampled on its own with :func:`systematic_resample`.

    Returns
    -------
    particles, weights, log_evidence ``(B,)``
    """
    particles = propagate(particles, rng)
    log_evidence = np.zeros(len(weights))
    if log_likelihood is not None:
        log_w = np.log(np.maximum(weights, 1e-300)) + log_likelihood(particles)
        peak = np.max(log_w, axis=1, keepdims=True)
        finite = np.isfinite(peak[:, 0])
        shifted = np.exp(log_w - np.where(finite[:, None], peak, 0.0))
        total = shifted.sum(axis=1, keepdims=True)
        ok = finite & (total[:, 0] > 0)
        weights = np.where(ok[:, None], shifted / np.where(ok[:, None], total, 1.0), 1.0 / weights.shape[1])
        log_evidence = np.where(ok, peak[:, 0] + np.log(np.where(ok, total[:, 0], 1.0)), -np.inf)
    ess = 1.0 / np.sum(np.square(weights), axis=1)
    low = np.flatnonzero(ess < resample_below * weights.shape[1])
    if len(low):
        particles = particles.copy()
        weights = weights.copy()
        for b in low:
            idx = systematic_resample(weights[b], rng)
            particles[b] = particles[b][idx]
            weights[b] = 1.0 / weights.shape[1]
    return particles, weights, log_evidence


def weighted_mean_cov(particles: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean ``(d,)`` and covariance ``(d, d)`` of ``(N, d)`` particles."""
    particles = particles.reshape(len(particles), -1)
    mean = weights @ particles
    d = particles - mean
    return mean, (weights[:, None] * d).T @ d


class ParticleFilter:
    """SIR particle filter holding ``(particles_, weights_)``.

    Parameters
    ----------
    propagate
        ``propagate(particles, rng) -> particles``: samples the transition density.
    log_likelihood
        ``log_likelihood(particles, z) -> (N,)`` log p(z | x).
    rng
        Random seed or Generator.
    resample_below
        Resample when the effective sample size falls below this fraction of N.
    """

    def __init__(self, propagate: Propagate, log_likelihood: Callable[[np.ndarray, object], np.ndarray],
                 rng: np.random.Generator | int | None = None, *, resample_below: float = 0.5) -> None:
        self.propagate = propagate
        self.log_likelihood = log_likelihood
        self.rng = rng
        self.resample_below = resample_below

    def initialize(self, particles: np.ndarray) -> None:
        """Start from samples of the prior ``(N, d)`` (or ``(N,)``)."""
        self.rng_ = np.random.default_rng(self.rng)
        self.particles_ = np.asarray(particles, dtype=float).copy()
        self.weights_ = np.full(len(self.particles_), 1.0 / len(self.particles_))

    def step(self, z=None) -> float:
        """Propagate and (if ``z`` is not None) weight by ``z``; returns the log evidence."""
        loglik = None if z is None else (lambda p: self.log_likelihood(p, z))
        self.particles_, self.weights_, log_evidence = sir_step(
            self.particles_, self.weights_, self.propagate, loglik, self.rng_, resample_below=self.resample_below)
        return log_evidence

    def mean(self) -> np.ndarray:
        return weighted_mean_cov(self.particles_, self.weights_)[0]
