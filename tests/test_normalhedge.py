"""NormalHedge maths (Algorithm 1) and the SMC tracker (Algorithms 2-3)."""

import numpy as np
import pytest
from scipy.special import logsumexp

from vidtrack.filters.normalhedge import (
    NormalHedgeTracker,
    nh_tracking_step,
    normalhedge_c,
    normalhedge_log_c,
    normalhedge_step,
    normalhedge_weights,
    resample_parents,
)


def equation_lhs_log(regrets, log_c):
    """log of (1/N) sum exp([R]_+^2 / 2c), evaluated independently in logs."""
    r = np.asarray(regrets, float)
    pos = r > 0
    terms = np.exp(np.where(pos, 2 * np.log(np.where(pos, r, 1.0)) - np.log(2.0) - log_c, -np.inf))
    return logsumexp(terms) - np.log(len(r))


EXTREME = [
    np.array([1.0, 2.0, 3.0, -1.0]),
    np.array([1e-8, 1e6, 1e12, 0.0]),
    np.r_[1e9, np.full(99, -5.0)],
    np.linspace(-1e7, 1e7, 1001),
    np.array([1e150, 1e-150, 3e149]),
    np.array([1e-200, 0.0, -3.0]),
    np.full(50, 7.5),
]


@pytest.mark.parametrize("regrets", EXTREME)
def test_c_solves_its_equation_to_1e_9_relative(regrets):
    log_c = normalhedge_log_c(regrets)
    assert np.isfinite(log_c)
    value = np.exp(equation_lhs_log(regrets, log_c))  # should equal e
    assert abs(value - np.e) / np.e < 1e-9


def test_c_matches_brute_force_bisection():
    rng = np.random.default_rng(3)
    r = rng.normal(0, 5, size=40)
    lo, hi = 1e-6, 1e6
    for _ in range(200):  # bisection on c directly (well-scaled problem)
        mid = np.sqrt(lo * hi)
        if np.mean(np.exp(np.maximum(r, 0) ** 2 / (2 * mid))) > np.e:
            lo = mid
        else:
            hi = mid
    assert normalhedge_c(r) == pytest.approx(np.sqrt(lo * hi), rel=1e-9)


def test_c_batched_equals_rowwise():
    rng = np.random.default_rng(0)
    r = rng.normal(0, 100, size=(6, 30))
    batched = normalhedge_log_c(r)
    assert np.allclose(batched, [normalhedge_log_c(row) for row in r], rtol=1e-12)


def test_no_positive_regret_gives_no_c_and_uniform_weights():
    r = np.array([0.0, -1.0, -5.0, 0.0])
    assert normalhedge_log_c(r) == -np.inf
    assert np.allclose(normalhedge_weights(r), 0.25)


@pytest.mark.parametrize("regrets", EXTREME + [np.random.default_rng(1).normal(0, 1e4, size=(4, 100))])
def test_weights_sum_to_one_and_zero_exactly_for_nonpositive_regret(regrets):
    w = normalhedge_weights(regrets)
    assert np.all(np.isfinite(w))
    assert np.allclose(w.sum(axis=-1), 1.0, rtol=0, atol=1e-12)
    assert np.all(w[np.asarray(regrets) <= 0] == 0.0)
    assert np.all(w[np.asarray(regrets) > 0] >= 0.0)


def test_weights_follow_the_formula():
    r = np.array([0.5, 1.0, 2.0, -1.0])
    c = normalhedge_c(r)
    raw = np.maximum(r, 0) / c * np.exp(np.maximum(r, 0) ** 2 / (2 * c))
    assert np.allclose(normalhedge_weights(r), raw / raw.sum(), rtol=1e-12)


def test_normalhedge_step_prefers_the_best_action():
    # Action 0 always has the lowest loss: it must end up with most weight.
    rng = np.random.default_rng(0)
    n = 10
    regrets, weights = np.zeros(n), np.full(n, 1.0 / n)
    for _ in range(200):
        losses = rng.uniform(0, 1, n)
        losses[0] -= 0.3
        regrets, weights, _ = normalhedge_step(regrets, weights, losses)
    assert np.argmax(weights) == 0 and weights[0] > 0.5


def test_resample_parents_only_positive_regret_and_proportional():
    rng = np.random.default_rng(0)
    regrets = np.array([1.0, -1.0, 2.0, 0.0])
    prev = np.array([0.1, 0.6, 0.3, 0.0])
    parents = resample_parents(np.broadcast_to(regrets, (4000, 4)), np.broadcast_to(prev, (4000, 4)), rng)
    counts = np.bincount(parents.ravel(), minlength=4) / parents.size
    assert counts[1] == 0 and counts[3] == 0
    assert counts[0] == pytest.approx(0.25, abs=0.02) and counts[2] == pytest.approx(0.75, abs=0.02)


def test_tracking_step_deletes_and_resamples_nonpositive_actions():
    rng = np.random.default_rng(0)
    states = np.linspace(-50, 50, 21)[:, None]

    def losses(s):
        return np.abs(s[..., 0] - 10.0)  # best action sits at x = 10

    out = nh_tracking_step(states, np.zeros(21), np.full(21, 1 / 21), losses, rng, alpha=0.02, sigma_star=2.0)
    moved = out["deleted"]
    assert moved.any() and not moved.all()
    # Kept actions keep their state; re-sampled ones land near positive-regret parents.
    assert np.all(out["states"][~moved] == states[~moved])
    assert np.all(np.abs(out["states"][moved, 0] - 10.0) < 40.0)
    assert np.all(out["weights"][out["regrets"] <= 0] == 0)
    assert abs(out["estimate"][0] - 10.0) < 5.0


def test_tracker_class_follows_a_moving_target():
    # F moves every action with the target's velocity (the dynamics function of Algorithm 2).
    tracker = NormalHedgeTracker(n_actions=100, alpha=0.02, sigma_star=5.0, dynamics=lambda s: s + 0.5, rng=1)
    tracker.initialize(np.random.default_rng(0).uniform(-100, 100, (100, 1)))
    errors = []
    for t in range(120):
        target = 0.5 * t

        def losses(s, target=target):
            return -np.clip(1.0 - np.abs(s[..., 0] - target) / 20.0, 0.0, 1.0)

        estimate = tracker.step(losses)
        errors.append(abs(estimate[0] - target))
    assert np.mean(errors[-50:]) < 2.0
    assert tracker.c > 0 and 0 < tracker.live_actions <= 100


def test_pruning_resamples_lagging_actions_that_exact_algorithm_keeps():
    # Noise-free equal losses: no regret changes sign, so Algorithm 2 deletes nothing, but
    # action 0's (old, small) regret gives it a negligible weight: pruning re-samples it.
    states = np.array([[0.0], [10.0], [10.5], [9.5]])
    regrets = np.array([0.05, 5.0, 5.0, 5.0])
    prev = normalhedge_weights(regrets)

    def losses(s):
        return np.ones(s.shape[:-1])

    exact = nh_tracking_step(states, regrets, prev, losses, np.random.default_rng(0), alpha=0.3, sigma_star=1.0)
    pruned = nh_tracking_step(states, regrets, prev, losses, np.random.default_rng(0), alpha=0.3, sigma_star=1.0,
                              prune_below=0.3)
    assert not exact["deleted"].any() and exact["regrets"][0] > 0
    assert pruned["deleted"][0] and not pruned["deleted"][1:].any()
    assert abs(pruned["states"][0, 0] - 10.0) < 5.0
