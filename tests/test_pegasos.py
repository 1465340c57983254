"""Pegasos (Shalev-Shwartz et al.) reaches the linear SVM optimum."""

import numpy as np
import pytest

from vidtrack.learn.pegasos import PegasosSVM, balanced_weights, pegasos_step, svm_objective


def separable_set(rng, n=60):
    X = np.vstack([rng.normal([2.0, 2.0], 0.4, (n // 2, 2)), rng.normal([-2.0, -1.0], 0.4, (n // 2, 2))])
    y = np.r_[np.ones(n // 2), -np.ones(n // 2)]
    return X, y


def reference_optimum(X, y, lam):
    """Minimise the same objective (bias as a regularised feature) with scipy."""
    from scipy.optimize import minimize

    Xa = np.hstack([X, np.ones((len(X), 1))])
    fun = lambda w: svm_objective(w, Xa, y, lam)  # noqa: E731
    best = min((minimize(fun, w0, method="Powell", options={"xtol": 1e-8, "ftol": 1e-12, "maxiter": 20000})
                for w0 in (np.zeros(3), np.ones(3))), key=lambda r: r.fun)
    return best.x, best.fun


def test_pegasos_reaches_the_svm_optimum_on_a_separable_set():
    rng = np.random.default_rng(0)
    X, y = separable_set(rng)
    lam = 0.05
    svm = PegasosSVM(lam=lam, n_iter=4000, balanced=False).fit(X, y)
    w_ref, f_ref = reference_optimum(X, y, lam)
    assert svm.objective(X, y) == pytest.approx(f_ref, abs=2e-3)
    assert np.allclose(svm.coef_, w_ref, atol=0.05)
    assert np.all(np.sign(svm.decision_function(X)) == y)


def test_projection_keeps_w_in_the_ball():
    rng = np.random.default_rng(1)
    X, y = separable_set(rng)
    Xa = np.hstack([X * 100.0, np.ones((len(X), 1))])
    lam = 0.1
    w = pegasos_step(np.zeros(3), Xa, y, 1, lam)
    assert np.linalg.norm(w) <= 1.0 / np.sqrt(lam) + 1e-9


def test_partial_fit_continues_and_minibatches_are_seeded():
    rng = np.random.default_rng(2)
    X, y = separable_set(rng, 100)
    a = PegasosSVM(lam=0.01, n_iter=50, batch_size=10, rng=3)
    b = PegasosSVM(lam=0.01, n_iter=50, batch_size=10, rng=3)
    a.partial_fit(X, y)
    b.partial_fit(X, y)
    assert np.array_equal(a.coef_, b.coef_)
    a.partial_fit(X, y)
    assert a.t_ == 100
    assert np.mean(np.sign(a.decision_function(X)) == y) == 1.0


def test_untrained_svm_scores_zero_like_w_equal_zero():
    # mil on a whole-frame box has no negative superpixel: it never trains, and must not crash
    svm = PegasosSVM()
    assert np.array_equal(svm.decision_function(np.ones((4, 3))), np.zeros(4))
    svm.partial_fit(np.ones((2, 3)), np.ones(2), n_iter=0)
    assert np.array_equal(svm.decision_function(np.ones((4, 3))), np.zeros(4))


@pytest.mark.parametrize("batch_size", [10, None])
def test_the_compiled_iterations_are_pegasos_step_repeated(batch_size):
    """PegasosSVM runs its iterations in one compiled call: the same iterates as pegasos_step on the same batches."""
    rng = np.random.default_rng(6)
    X, y = separable_set(rng, 80)
    svm = PegasosSVM(lam=0.05, n_iter=25, batch_size=batch_size, max_t=15, rng=7).partial_fit(X, y)
    draw = np.random.default_rng(7)
    Xa = np.hstack([X, np.ones((len(X), 1))])
    w, total = np.zeros(3), np.zeros(3)
    for t in range(1, 26):
        idx = draw.choice(len(y), size=batch_size, replace=False) if batch_size else np.arange(len(y))
        w = pegasos_step(w, Xa[idx], y[idx], min(t, 15), 0.05, balanced_weights(y)[idx])
        total += w
    assert np.allclose(svm.coef_, w, rtol=1e-12, atol=1e-12)
    assert np.allclose(svm.avg_coef_, total / 25, rtol=1e-12, atol=1e-12)


def test_partial_fit_on_blocks_of_rows_equals_partial_fit_on_their_stack():
    """Training triples of several frames may be given as blocks: the same iterates as their concatenation."""
    rng = np.random.default_rng(2)
    blocks = [rng.normal(size=(n, 6)).astype(np.float32) for n in (7, 12, 5)]
    y = np.where(rng.random(24) > 0.5, 1, -1)
    stacked = PegasosSVM(lam=1e-2, batch_size=8, n_iter=25, rng=3).partial_fit(np.concatenate(blocks), y)
    in_blocks = PegasosSVM(lam=1e-2, batch_size=8, n_iter=25, rng=3).partial_fit(blocks, y)
    assert np.array_equal(in_blocks.coef_, stacked.coef_)
    assert np.array_equal(in_blocks.avg_coef_, stacked.avg_coef_)
