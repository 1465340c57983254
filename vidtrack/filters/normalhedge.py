"""NormalHedge and its Sequential Monte Carlo tracker: pure maths and a thin class.

From Chaudhuri, Freund & Hsu, "An Online Learning-based Framework for
Tracking" (UAI 2010), which builds on "A parameter-free hedging algorithm"
(NIPS 2009).

NormalHedge (Algorithm 1) weighs ``N`` actions by their regrets ``R_i``::

    (1/N) sum_i exp([R_i]_+^2 / (2 c)) = e                 (scale c_t)
    w_i ∝ ([R_i]_+ / c) exp([R_i]_+^2 / (2 c))             (weights)

The tracker (Algorithm 2) keeps ``N`` actions = current states of paths,
discounts the regrets by ``1 - alpha``, deletes every action with
``R_i <= 0`` and re-samples it (Algorithm 3) near an action drawn with
probability ∝ its previous weight among the positive-regret ones (Gaussian
with covariance ``Sigma_*``; the new action inherits the parent's regret
history), then moves every action by the dynamics function ``F``.

Everything works on a leading batch axis: ``regrets`` of shape ``(..., N)``
holds independent problems (the 1-D experiment runs all its simulations at
once).  The root finder works with ``u = log c`` and log-sum-exp, so regrets
of any magnitude (1e-6 ... 1e12) are handled without overflow.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

#: ``losses(states) -> (..., N)`` per-action observation loss ``l_o(x_i, M_t)``.
LossFn = Callable[[np.ndarray], np.ndarray]
#: ``F(states) -> states``: the dynamics function of Algorithm 2.
DynamicsFn = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------- NormalHedge


def logsumexp(a: np.ndarray, axis: int = -1, keepdims: bool = False) -> np.ndarray:
    """``log sum exp(a)`` along ``axis``, shifted by the maximum (``-inf`` where every entry is ``-inf``).

    The same as :func:`scipy.special.logsumexp` for real input without
    weights, without its per-call overhead (NormalHedge's Newton iterations
    call it several times per frame).
    """
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - m), axis=axis, keepdims=True)) + m
    return out if keepdims else np.squeeze(out, axis=axis)


def normalhedge_log_c(regrets: np.ndarray, *, max_iter: int = 200, tol: float = 1e-15) -> np.ndarray:
    """``log c_t`` solving ``mean_i exp([R_i]_+^2 / 2c) = e`` (Algorithm 1), per problem.

    With ``s_i = [R_i]_+^2 / 2`` and ``u = log c`` the equation is
    ``f(u) = logsumexp(s_i e^{-u}) - log N - 1 = 0``; ``f`` is decreasing and
    convex in ``u`` and has its root in ``[log(s_max / (1 + log N)), log s_max]``
    (at the left end the largest term alone reaches ``N e``; at the right end
    every term is at most ``e``).  Newton's method started at the left end of
    that bracket therefore increases monotonically to the root without
    overshooting (tangents of a convex decreasing function lie below it);
    it is clamped to the bracket for safety.

    Parameters
    ----------
    regrets : (..., N) float
        Regrets; non-positive ones do not enter the equation but count in ``N``.

    Returns
    -------
    log_c : (...) float
        ``-inf`` where every regret is non-positive (no ``c > 0`` solves the
        equation: the left side is 1 for every ``c``).
    """
    r = np.asarray(regrets, dtype=float)
    n = r.shape[-1]
    pos = r > 0
    with np.errstate(divide="ignore"):
        log_s = np.where(pos, 2.0 * np.log(np.where(pos, r, 1.0)) - np.log(2.0), -np.inf)   # log([R]_+^2 / 2)
    log_s_max = log_s.max(axis=-1)
    positive = np.isfinite(log_s_max)
    safe_max = np.where(positive, log_s_max, 0.0)
    target = np.log(n) + 1.0
    # v = u - log s_max lies in [-log(1 + log N), 0]; s_i / c = exp(log s_i - log s_max - v) <= exp(-v).
    rel = np.where(pos, log_s - safe_max[..., None], -np.inf)
    v_lo, v_hi = -np.log(target), 0.0
    v = np.full(safe_max.shape, v_lo)
    for _ in range(max_iter):
        a = np.exp(rel - v[..., None])            # s_i / c  (0 for non-positive regrets)
        lse = logsumexp(a, axis=-1)
        f = lse - target                          # f(u)
        p = np.exp(a - lse[..., None])
        df = -np.sum(p * a, axis=-1)              # f'(u) = -E_p[s / c]
        step = np.where(df < 0, -f / np.where(df < 0, df, -1.0), 0.0)
        v_new = np.clip(v + step, v_lo, v_hi)
        done = np.all(np.abs(v_new - v) <= tol)
        v = v_new
        if done:
            break
    return np.where(positive, v + safe_max, -np.inf)


def normalhedge_c(regrets: np.ndarray) -> np.ndarray:
    """``c_t`` of Algorithm 1 (0 where every regret is non-positive); see :func:`normalhedge_log_c`."""
    return np.exp(normalhedge_log_c(regrets))


def normalhedge_weights(regrets: np.ndarray, log_c: np.ndarray | None = None) -> np.ndarray:
    """NormalHedge weights ``w_i ∝ ([R_i]_+ / c) exp([R_i]_+^2 / 2c)`` (Algorithm 1).

    Computed in logs.  An action with ``R_i <= 0`` gets exactly zero weight.
    Where every regret is non-positive the weights are uniform (Algorithm 1's
    initial ``w_i = 1/N``).

    Parameters
    ----------
    regrets : (..., N)
    log_c : (...) optional, precomputed :func:`normalhedge_log_c`.

    Returns
    -------
    weights : (..., N), each row summing to 1.
    """
    r = np.asarray(regrets, dtype=float)
    if log_c is None:
        log_c = normalhedge_log_c(r)
    log_c = np.asarray(log_c, dtype=float)
    positive = r > 0
    any_positive = positive.any(axis=-1)
    lc = np.where(any_positive, log_c, 0.0)[..., None]
    with np.errstate(divide="ignore"):
        log_r = np.log(np.where(positive, r, 1.0))
    # log w = log R - log c + exp(2 log R - log 2 - log c) ; the last term in logs avoids R^2 overflow
    exponent = np.where(positive, 2.0 * log_r - np.log(2.0) - lc, -np.inf)
    log_w = np.where(positive, log_r - lc + np.exp(exponent), -np.inf)
    norm = logsumexp(np.where(any_positive[..., None], log_w, 0.0), axis=-1, keepdims=True)
    w = np.where(any_positive[..., None], np.exp(log_w - norm), 1.0 / r.shape[-1])
    w = np.where(any_positive[..., None] & ~positive, 0.0, w)
    return w / w.sum(axis=-1, keepdims=True)


def discounted_regrets(regrets: np.ndarray, weights: np.ndarray, losses: np.ndarray,
                       alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """``(l_A, R)``: ``l_A = sum_i w_i l_i`` and ``R_i <- (1 - alpha) R_i + (l_A - l_i)`` (Algorithms 1-2)."""
    learner_loss = np.sum(weights * losses, axis=-1, keepdims=True)   # l_A,t
    return learner_loss, (1.0 - alpha) * regrets + (learner_loss - losses)


def normalhedge_step(regrets: np.ndarray, weights: np.ndarray, losses: np.ndarray,
                     alpha: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One round of (discounted) NormalHedge.

    ``l_A = sum_i w_i l_i``; ``R_i <- (1 - alpha) R_i + (l_A - l_i)``; new
    weights from the new regrets (Algorithm 1; ``alpha > 0`` is the
    discounting of Algorithm 2).

    Returns
    -------
    regrets, weights, log_c
    """
    _, regrets = discounted_regrets(regrets, weights, losses, alpha)
    log_c = normalhedge_log_c(regrets)
    return regrets, normalhedge_weights(regrets, log_c), log_c


# -------------------------------------------------------- SMC tracker (Alg. 2-3)


def resample_parents(regrets: np.ndarray, prev_weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Parent index for every action (Algorithm 3's multinomial draw), shape ``(..., N)``.

    ``p_i ∝ w_{i,t-1}`` over actions with ``R_{i,t} > 0``; uniform over them
    if their previous weights sum to zero; uniform over all ``N`` when no
    regret is positive.  Every action gets a parent; callers keep the
    parent only where the action is deleted.
    """
    positive = regrets > 0
    n = regrets.shape[-1]
    p = np.where(positive, prev_weights, 0.0)
    total = p.sum(axis=-1, keepdims=True)
    p = np.where(total > 0, p, positive.astype(float))
    total = p.sum(axis=-1, keepdims=True)
    p = np.where(total > 0, p / np.where(total > 0, total, 1.0), 1.0 / n)
    cdf = np.cumsum(p, axis=-1)
    cdf[..., -1] = 1.0
    u = rng.random(regrets.shape)
    idx = np.sum(u[..., :, None] >= cdf[..., None, :], axis=-1)   # inverse-CDF draw per action
    return np.minimum(idx, n - 1)


def nh_tracking_step(states: np.ndarray, regrets: np.ndarray, prev_weights: np.ndarray, losses_fn: LossFn,
                     rng: np.random.Generator, *, alpha: float, sigma_star: np.ndarray | float,
                     dynamics: DynamicsFn | None = None, prune_below: float = 0.0) -> dict[str, np.ndarray]:
    """One round ``t`` of the NormalHedge tracking algorithm (Algorithms 2 and 3).

    Parameters
    ----------
    states : (..., N, d)
        Current action states ``x_{i,t}`` (already moved by ``F``).
    regrets : (..., N)
        ``R_{i,t-1}``.
    prev_weights : (..., N)
        ``w_{i,t-1}``.
    losses_fn
        ``losses_fn(states) -> (..., N)``: observation loss ``l_o(x_i, M_t)``.
    alpha
        Discount of the regrets.
    sigma_star
        Re-sampling standard deviation per state dimension (``Sigma_*``
        diagonal square root), scalar or ``(d,)``.
    dynamics
        ``F``; identity when None.
    prune_below
        Also delete (and re-sample) actions whose NormalHedge weight is below
        ``prune_below / N`` ("when its weight falls to 0", Section 4, read
        numerically).  0 (default) is Algorithm 2 exactly: only ``R <= 0``.
        With noise-free losses the discounted regret of an action that has
        fallen behind decays towards 0 without ever reaching it, so without
        pruning such actions are never re-sampled.

    Returns
    -------
    dict with ``states`` (``x_{i,t}`` after re-sampling), ``regrets``
    ``R_{i,t}``, ``weights`` ``w_{i,t}``, ``log_c``, ``estimate``
    ``x_{A,t} = sum_i w_i x_i`` ``(..., d)``, ``deleted`` (bool ``(..., N)``),
    ``next_states`` (``F(x_{i,t})``, the states of round ``t + 1``).
    """
    losses = losses_fn(states)
    learner_loss, new_regrets = discounted_regrets(regrets, prev_weights, losses, alpha)   # l_A,t; R_i,t
    deleted = new_regrets <= 0                                              # X = {i : R_i,t <= 0}
    if prune_below > 0:
        n = new_regrets.shape[-1]
        deleted |= normalhedge_weights(new_regrets) < prune_below / n
    if np.any(deleted):
        parents = resample_parents(np.where(deleted, 0.0, new_regrets), prev_weights, rng)
        parent_states = np.take_along_axis(states, parents[..., None], axis=-2)
        noise = rng.standard_normal(states.shape) * np.asarray(sigma_star, dtype=float)
        proposed = parent_states + noise                                    # x_j ~ N(x_i, Sigma_*)
        states = np.where(deleted[..., None], proposed, states)
        inherited = np.take_along_axis(regrets, parents, axis=-1)           # history of the parent
        new_losses = losses_fn(states)
        resampled_regrets = (1.0 - alpha) * inherited + (learner_loss - new_losses)
        new_regrets = np.where(deleted, resampled_regrets, new_regrets)
    log_c = normalhedge_log_c(new_regrets)
    weights = normalhedge_weights(new_regrets, log_c)
    estimate = np.sum(weights[..., None] * states, axis=-2)                 # x_A,t
    next_states = states if dynamics is None else dynamics(states)          # x_i,t+1 = F(x_i,t)
    return {"states": states, "regrets": new_regrets, "weights": weights, "log_c": log_c,
            "estimate": estimate, "deleted": deleted, "next_states": next_states}


def weight_concentration(states: np.ndarray, weights: np.ndarray, estimate: np.ndarray, radius: float) -> float:
    """Weight mass of the actions within ``radius`` of ``estimate`` (a confidence in [0, 1])."""
    d = np.linalg.norm(np.asarray(states) - np.asarray(estimate), axis=-1)
    return float(np.clip(np.sum(np.where(d <= radius, weights, 0.0)), 0.0, 1.0))


class NormalHedgeTracker:
    """The SMC NormalHedge tracker of Algorithm 2 over a point state.

    Parameters
    ----------
    n_actions
        ``N``.
    alpha
        Regret discount ``alpha`` (the paper's 1-D experiment: 0.02).
    sigma_star
        Re-sampling standard deviation per dimension (``sqrt`` of the
        diagonal of ``Sigma_*``; the paper's 1-D experiment: ``sqrt(400) = 20``).
    dynamics
        ``F``; identity when None.
    rng
        Random seed or Generator.
    prune_below
        See :func:`nh_tracking_step` (0: Algorithm 2 exactly).
    """

    def __init__(self, n_actions: int = 100, alpha: float = 0.02, sigma_star: float | np.ndarray = 20.0,
                 dynamics: DynamicsFn | None = None, rng: np.random.Generator | int | None = None,
                 prune_below: float = 0.0) -> None:
        self.prune_below = prune_below
        self.n_actions = n_actions
        self.alpha = alpha
        self.sigma_star = sigma_star
        self.dynamics = dynamics
        self.rng = rng

    def initialize(self, states: np.ndarray) -> None:
        """Start from action states ``(N, d)`` (``R = 0``, ``w = 1/N``)."""
        self.rng_ = np.random.default_rng(self.rng)
        self.states_ = np.asarray(states, dtype=float).reshape(self.n_actions, -1).copy()
        self.regrets_ = np.zeros(self.n_actions)
        self.weights_ = np.full(self.n_actions, 1.0 / self.n_actions)
        self.log_c_ = -np.inf
        self.estimate_ = self.weights_ @ self.states_

    def predict(self) -> np.ndarray:
        """The estimate the current weights give at the current (moved) states."""
        return self.weights_ @ self.states_

    def step(self, losses_fn: LossFn) -> np.ndarray:
        """One round with the losses of this time step; returns ``x_{A,t}``."""
        out = nh_tracking_step(self.states_, self.regrets_, self.weights_, losses_fn, self.rng_,
                               alpha=self.alpha, sigma_star=self.sigma_star, dynamics=self.dynamics,
                               prune_below=self.prune_below)
        self.regrets_, self.weights_, self.log_c_ = out["regrets"], out["weights"], float(out["log_c"])
        self.current_states_ = out["states"]
        self.states_ = out["next_states"]
        self.estimate_ = out["estimate"]
        self.deleted_ = int(out["deleted"].sum())
        return self.estimate_

    @property
    def c(self) -> float:
        """The scale ``c_t`` of the last round (0 before any positive regret)."""
        return float(np.exp(self.log_c_))

    @property
    def live_actions(self) -> int:
        """Number of actions with positive regret (non-zero weight)."""
        return int(np.sum(self.regrets_ > 0))
