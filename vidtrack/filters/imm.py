"""Interacting Multiple Model estimator (Blom & Bar-Shalom, 1988).

A bank of Kalman filters sharing one state space (models of lower order are
embedded with zero rows, see :func:`vidtrack.filters.kalman.axis_transition`)
and a Markov chain over which model is in force, with transition probability
matrix ``M[i, j] = P(model j at k | model i at k-1)``.

One cycle:

1. mixing: ``c_j = sum_i M_ij mu_i``; ``mu_{i|j} = M_ij mu_i / c_j``;
   ``x0_j = sum_i mu_{i|j} x_i``;
   ``P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)')``;
2. model-matched prediction and update of each filter from ``(x0_j, P0_j)``;
3. mode probabilities ``mu_j = c_j L_j / sum_l c_l L_l`` with ``L_j`` the
   likelihood of the innovation of filter ``j``;
4. combination ``x = sum_j mu_j x_j``, ``P = sum_j mu_j (P_j + (x_j-x)(x_j-x)')``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .kalman import KalmanFilter


def imm_mix(xs: np.ndarray, Ps: np.ndarray, mu: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mixing step. Returns ``(x0, P0, c)``: mixed means ``(r, n)``, covariances ``(r, n, n)``, ``c (r,)``."""
    c = M.T @ mu  # c_j = sum_i M_ij mu_i
    w = (M * mu[:, None]) / np.maximum(c[None, :], 1e-300)  # w[i, j] = mu_{i|j}
    x0 = w.T @ xs
    P0 = np.empty_like(Ps)
    for j in range(len(mu)):
        d = xs - x0[j]
        P0[j] = np.einsum("i,ikl->kl", w[:, j], Ps + d[:, :, None] * d[:, None, :])
    return x0, P0, c


def imm_combine(xs: np.ndarray, Ps: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moment-matched combination ``(x, P)`` of the model-conditioned estimates."""
    x = mu @ xs
    d = xs - x
    P = np.einsum("j,jkl->kl", mu, Ps + d[:, :, None] * d[:, None, :])
    return x, 0.5 * (P + P.T)


def uniform_transition_matrix(r: int) -> np.ndarray:
    """The uniform TPM ``M_ij = 1/r`` (as used by Salti & Di Stefano's IMM)."""
    return np.full((r, r), 1.0 / r)


def sticky_transition_matrix(r: int, stay: float = 0.95) -> np.ndarray:
    """TPM with probability ``stay`` of keeping the current model."""
    M = np.full((r, r), (1.0 - stay) / max(r - 1, 1))
    np.fill_diagonal(M, stay if r > 1 else 1.0)
    return M


class IMMEstimator:
    """IMM over Kalman filters that share one state space.

    Parameters
    ----------
    filters
        :class:`KalmanFilter` objects (any object with ``F, Q, H, R``, ``x_``,
        ``P_`` and ``predict``/``update`` quacks right).
    transition
        Mode transition probability matrix ``(r, r)``; rows sum to 1.
    mu0
        Initial mode probabilities (uniform by default).
    """

    def __init__(self, filters: Sequence[KalmanFilter], transition: np.ndarray,
                 mu0: np.ndarray | None = None) -> None:
        self.filters = list(filters)
        self.transition = np.asarray(transition, dtype=float)
        self.mu0 = None if mu0 is None else np.asarray(mu0, dtype=float)

    def initialize(self, x0: np.ndarray, P0: np.ndarray) -> None:
        r = len(self.filters)
        for f in self.filters:
            f.initialize(x0, P0)
        self.mu_ = np.full(r, 1.0 / r) if self.mu0 is None else self.mu0.copy()
        self.c_ = self.mu_.copy()
        self.x_, self.P_ = np.asarray(x0, float).copy(), np.asarray(P0, float).copy()
        self.log_likelihood_ = 0.0

    def _mix(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each model's mixed initial condition and the predicted mode probabilities ``c`` (:func:`imm_mix`)."""
        xs = np.array([f.x_ for f in self.filters])
        Ps = np.array([f.P_ for f in self.filters])
        return imm_mix(xs, Ps, self.mu_, self.transition)

    def _mode_probabilities(self, logL: np.ndarray) -> np.ndarray:
        """``mu ∝ c L_j`` from the models' log-likelihoods (shifted by the maximum; sets ``log_likelihood_``)."""
        log_post = np.log(np.maximum(self.c_, 1e-300)) + logL
        shift = log_post.max()
        weights = np.exp(log_post - shift)
        self.log_likelihood_ = float(shift + np.log(weights.sum()))
        return weights / weights.sum()

    def predict(self) -> tuple[np.ndarray, np.ndarray]:
        """Mix, predict every model, and return the combined prior."""
        x0s, P0s, self.c_ = self._mix()
        for f, x0, P0 in zip(self.filters, x0s, P0s):
            f.x_, f.P_ = x0, P0
            f.predict()
        # Without a measurement the mode probabilities are the predicted ones.
        self.mu_ = self.c_ / self.c_.sum()
        self._combine()
        return self.x_, self.P_

    def update(self, z: np.ndarray, R: np.ndarray | None = None) -> None:
        """Update every model with ``z`` and re-weight the modes."""
        logL = np.array([f.update(z, R).log_likelihood for f in self.filters])
        self.mu_ = self._mode_probabilities(logL)
        self._combine()

    def _combine(self) -> None:
        xs = np.array([f.x_ for f in self.filters])
        Ps = np.array([f.P_ for f in self.filters])
        self.x_, self.P_ = imm_combine(xs, Ps, self.mu_)


# --------------------------------------------------------------------- models of different order


def pad_state(x: np.ndarray, P: np.ndarray, n: int, fill_x: np.ndarray, fill_P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Extend a prefix state ``(x, P)`` to ``n`` components with ``fill_x`` and the block ``fill_P`` (zero cross terms)."""
    k = len(x)
    X = np.array(fill_x, dtype=float)[:n].copy()
    PP = np.zeros((n, n))
    PP[k:, k:] = np.asarray(fill_P, dtype=float)[k:n, k:n]
    X[:k] = x
    PP[:k, :k] = P
    return X, PP


def mixed_order_mix(xs: Sequence[np.ndarray], Ps: Sequence[np.ndarray], mu: np.ndarray, M: np.ndarray, *,
                    pad: str = "zero", pad_var: float = 0.0) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """IMM mixing for models whose states are prefixes of one state (``[p]``, ``[p, v]``, ``[p, v, a]``).

    Model ``j`` receives from model ``i`` only its own ``n_j`` components.
    When ``i`` carries fewer, the missing ones are augmented:

    * ``pad="zero"``: mean 0, variance ``pad_var`` (0: the lower model is
      certain the derivative is zero, as in state augmentation with zeros;
      large: it says nothing about it);
    * ``pad="own"``: model ``j``'s own previous estimate of them (mean and
      covariance block), so a lower model never drags them.

    Returns per-model mixed means and covariances (native sizes) and ``c``.
    """
    c = M.T @ mu  # c_j = sum_i M_ij mu_i
    w = (M * mu[:, None]) / np.maximum(c[None, :], 1e-300)  # w[i, j] = mu_{i|j}
    x0s, P0s = [], []
    for j, (xj, Pj) in enumerate(zip(xs, Ps)):
        n = len(xj)
        if pad == "own":
            fill_x, fill_P = xj, Pj
        elif pad == "zero":
            fill_x, fill_P = np.zeros(n), pad_var * np.eye(n)
        else:
            raise ValueError(f"pad must be 'zero' or 'own', got {pad!r}")
        src = [pad_state(x[:n], P[:n, :n], n, fill_x, fill_P) if len(x) < n else (x[:n], P[:n, :n])
               for x, P in zip(xs, Ps)]
        x0 = sum(w[i, j] * s[0] for i, s in enumerate(src))
        P0 = sum(w[i, j] * (s[1] + np.outer(s[0] - x0, s[0] - x0)) for i, s in enumerate(src))
        x0s.append(x0)
        P0s.append(0.5 * (P0 + P0.T))
    return x0s, P0s, c


def float_mode_probabilities(c: np.ndarray, log_likelihoods: np.ndarray, dtype=np.float64) -> np.ndarray:
    """``mu_j = c_j L_j / sum_l c_l L_l`` with the densities ``L_j = exp(log L_j)`` evaluated in ``dtype``.

    In float64 each ``L_j`` underflows to 0 below ``exp(-745)`` (a
    Mahalanobis distance of about 38), in float32 below ``exp(-104)`` (about
    14); when every one does, ``0 / 0`` is replaced by the predicted
    probabilities ``c``, which is what a guarded direct implementation does.
    """
    with np.errstate(under="ignore"):
        L = np.exp(np.asarray(log_likelihoods, dtype=dtype)).astype(float)
    post = np.asarray(c, float) * L
    total = float(post.sum())
    return post / total if total > 0 else np.asarray(c, float) / float(np.sum(c))


class MixedOrderIMM(IMMEstimator):
    """IMM over Kalman filters of *different* state sizes (prefixes of one state), see :func:`mixed_order_mix`.

    Parameters
    ----------
    filters
        Kalman filters in their native sizes (e.g. DR ``[p]``, CV ``[p, v]``,
        CA ``[p, v, a]``), each with its own ``H`` onto the shared measurement.
    transition
        Mode transition probability matrix ``(r, r)``.
    pad, pad_var
        How a lower-order model's missing components enter the mixing.
    estimate
        ``"combined"``: the moment-matched mixture (missing components
        counted as 0); ``"mode"``: the most likely model's own estimate.
    likelihood
        ``"log"``: mode probabilities from log-likelihoods (numerically
        sound); ``"float64"`` / ``"float32"``: from the Gaussian densities
        evaluated in that precision, as a direct implementation computes
        them -- they underflow to 0 once the innovation is beyond about 38 /
        14 sigma, and when every model's does, the mode probabilities fall
        back to the predicted ones ``c`` (:func:`float_mode_probabilities`).
    """

    def __init__(self, filters: Sequence[KalmanFilter], transition: np.ndarray, *, pad: str = "zero",
                 pad_var: float = 0.0, estimate: str = "combined", likelihood: str = "log") -> None:
        super().__init__(filters, transition)
        self.pad = pad
        self.pad_var = pad_var
        self.estimate = estimate
        self.likelihood = likelihood

    @property
    def n_state(self) -> int:
        return max(f.F.shape[0] for f in self.filters)

    def initialize(self, x0: np.ndarray, P0: np.ndarray) -> None:
        """Every model starts from the prefix of ``(x0, P0)`` (full size) it carries."""
        for f in self.filters:
            n = f.F.shape[0]
            f.initialize(np.asarray(x0, float)[:n], np.asarray(P0, float)[:n, :n])
        r = len(self.filters)
        self.mu_ = np.full(r, 1.0 / r)
        self.c_ = self.mu_.copy()
        self.log_likelihood_ = 0.0
        self._combine()

    def _mix(self) -> tuple[list, list, np.ndarray]:
        return mixed_order_mix([f.x_ for f in self.filters], [f.P_ for f in self.filters], self.mu_,
                               self.transition, pad=self.pad, pad_var=self.pad_var)

    def _mode_probabilities(self, logL: np.ndarray) -> np.ndarray:
        if self.likelihood in ("float64", "float32"):
            return float_mode_probabilities(self.c_, logL, np.dtype(self.likelihood))
        return super()._mode_probabilities(logL)

    def _combine(self) -> None:
        n = self.n_state
        full = [pad_state(f.x_, f.P_, n, np.zeros(n), np.zeros((n, n))) if len(f.x_) < n else (f.x_, f.P_)
                for f in self.filters]
        xs, Ps = np.array([x for x, _ in full]), np.array([P for _, P in full])
        if self.estimate == "mode":
            j = int(np.argmax(self.mu_))
            self.x_, self.P_ = xs[j].copy(), Ps[j].copy()
        else:
            self.x_, self.P_ = imm_combine(xs, Ps, self.mu_)
