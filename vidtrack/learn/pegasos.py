"""Pegasos: primal estimated sub-gradient solver for the linear SVM.

Shalev-Shwartz, Singer & Srebro, *Pegasos: Primal Estimated sub-GrAdient
SOlver for SVM* (ICML 2007), the learner of *Multiple Instance Filtering*.
It minimises::

    f(w) = lambda/2 ||w||^2 + 1/m sum_i c_i max(0, 1 - y_i <w, x_i>)

(``c_i`` optional class weights; a bias is learned as the weight of a
constant feature ``bias_scale``, regularised like the others, as in the
paper).  Iteration ``t`` takes a mini-batch ``A_t``, the step
``eta_t = 1 / (lambda t)`` and::

    A_t+ = {i in A_t : y_i <w, x_i> < 1}
    w <- (1 - eta_t lambda) w + eta_t / |A_t| sum_{i in A_t+} c_i y_i x_i
    w <- min(1, (1/sqrt(lambda)) / ||w||) w          # projection step

The optimum lies in the ball ``||w|| <= 1/sqrt(lambda)`` (Pegasos, Thm. 1),
so the projection never excludes it.
"""

from __future__ import annotations

from typing import Sequence

import numba
import numpy as np


def pegasos_step(w: np.ndarray, X: np.ndarray, y: np.ndarray, t: int, lam: float,
                 weights: np.ndarray | None = None) -> np.ndarray:
    """One Pegasos iteration on the mini-batch ``(X, y)`` at iteration count ``t >= 1``.

    ``X`` ``(k, D)`` already holds the bias column; ``y`` in ``{-1, +1}``.
    Returns the new ``w`` (input not modified).
    """
    eta = 1.0 / (lam * t)
    margins = y * (X @ w)
    active = margins < 1.0
    coef = y[active] if weights is None else (y * weights)[active]
    grad_data = coef @ X[active] if np.any(active) else np.zeros_like(w)
    w = (1.0 - eta * lam) * w + (eta / len(y)) * grad_data  # w = (1 - eta lam) w + eta/|A| sum y x
    norm = np.linalg.norm(w)
    radius = 1.0 / np.sqrt(lam)
    if norm > radius:  # projection onto {||w|| <= 1/sqrt(lam)}
        w = w * (radius / norm)
    return w


@numba.njit(cache=True, nogil=True)
def pegasos_steps(w: np.ndarray, X: np.ndarray, y: np.ndarray, weights: np.ndarray, batches: np.ndarray,
                  n_iter: int, t_first: int, max_t: int, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """``n_iter`` iterations of :func:`pegasos_step`, compiled (no GIL, no copies of the mini-batches).

    Iteration ``i`` uses the rows ``batches[i]`` of ``X`` (with the bias
    column; every row when ``batches`` has no rows) at iteration count
    ``min(t_first + i, max_t)`` (``max_t <= 0``: uncapped); ``weights`` are
    the per-sample class weights (ones for none).  Returns the last iterate
    and the sum of the iterates.
    """
    w = w.copy()
    total = np.zeros_like(w)
    grad = np.empty_like(w)
    D = X.shape[1]
    radius = 1.0 / np.sqrt(lam)
    full = batches.shape[0] == 0
    size = X.shape[0] if full else batches.shape[1]
    for i in range(n_iter):
        t = t_first + i
        if max_t > 0 and t > max_t:
            t = max_t
        eta = 1.0 / (lam * t)
        grad[:] = 0.0
        for j in range(size):
            r = j if full else batches[i, j]
            margin = 0.0
            for d in range(D):
                margin += X[r, d] * w[d]
            if y[r] * margin < 1.0:                        # A_t+: the samples inside the margin
                c = y[r] * weights[r]
                for d in range(D):
                    grad[d] += c * X[r, d]
        scale = eta / size
        norm2 = 0.0
        for d in range(D):                                 # w = (1 - eta lam) w + eta/|A| sum c y x
            w[d] = (1.0 - eta * lam) * w[d] + scale * grad[d]
            norm2 += w[d] * w[d]
        norm = np.sqrt(norm2)
        if norm > radius:                                  # projection onto {||w|| <= 1/sqrt(lam)}
            for d in range(D):
                w[d] *= radius / norm
        for d in range(D):
            total[d] += w[d]
    return w, total


def svm_objective(w: np.ndarray, X: np.ndarray, y: np.ndarray, lam: float,
                  weights: np.ndarray | None = None) -> float:
    """``lambda/2 ||w||^2 + 1/m sum c_i max(0, 1 - y_i <w, x_i>)`` (``X`` with bias column)."""
    hinge = np.maximum(0.0, 1.0 - y * (X @ w))
    if weights is not None:
        hinge = hinge * weights
    return float(0.5 * lam * w @ w + hinge.mean())


def balanced_weights(y: np.ndarray) -> np.ndarray:
    """Per-sample weights ``m / (2 m_class)``: both classes weigh the same in the loss."""
    y = np.asarray(y)
    pos = max(int(np.sum(y > 0)), 1)
    neg = max(int(np.sum(y <= 0)), 1)
    return np.where(y > 0, len(y) / (2.0 * pos), len(y) / (2.0 * neg))


class PegasosSVM:
    """Linear SVM trained incrementally with Pegasos (``partial_fit`` style).

    Parameters
    ----------
    lam
        Regularisation ``lambda``.
    batch_size
        Mini-batch size ``k`` (``None``: the whole set given to ``partial_fit``).
    n_iter
        Iterations per ``partial_fit`` call.
    bias_scale
        Value of the constant feature carrying the bias.
    balanced
        Weight the classes equally in the hinge loss.
    max_t
        Cap on the iteration counter, so the step size ``1/(lambda t)`` never
        falls below ``1/(lambda max_t)`` and the model keeps adapting on a
        long video (``None``: the plain Pegasos schedule).
    average
        Score with the mean of the iterates of the last ``partial_fit`` call
        (iterate averaging, which lowers the variance of the stochastic
        steps) instead of the last iterate; training continues from the last
        iterate either way.
    rng
        Generator, seed or None for the mini-batch sampling.
    """

    def __init__(self, *, lam: float = 1e-2, batch_size: int | None = None, n_iter: int = 20,
                 bias_scale: float = 1.0, balanced: bool = True, max_t: int | None = None,
                 average: bool = False, rng: np.random.Generator | int | None = None) -> None:
        self.lam = lam
        self.average = average
        self.batch_size = batch_size
        self.n_iter = n_iter
        self.bias_scale = bias_scale
        self.balanced = balanced
        self.max_t = max_t
        self.rng = rng

    def _augment(self, blocks: list[np.ndarray]) -> np.ndarray:
        """The rows of ``blocks`` stacked in order, each followed by the constant ``bias_scale``: one copy."""
        rows, columns = sum(len(b) for b in blocks), blocks[0].shape[1]
        out = np.empty((rows, columns + 1))
        out[:, columns] = self.bias_scale
        start = 0
        for block in blocks:
            out[start:start + len(block), :columns] = block
            start += len(block)
        return out

    def partial_fit(self, X: np.ndarray | Sequence[np.ndarray], y: np.ndarray, *, n_iter: int | None = None
                    ) -> "PegasosSVM":
        """Run ``n_iter`` Pegasos iterations on ``(X, y)``, continuing from the current ``w``.

        ``X``: ``(m, d)`` samples, or a sequence of ``(m_i, d)`` blocks of
        them (stacked in order, without a concatenated copy); ``y`` in
        ``{-1, +1}`` (or ``{0, 1}``, mapped to ``{-1, +1}``).
        """
        if isinstance(X, (list, tuple)) and X and all(isinstance(b, np.ndarray) and b.ndim == 2 for b in X):
            blocks = list(X)
        else:
            blocks = [np.asarray(X)]   # one copy, to float, in _augment
        y = np.where(np.asarray(y) > 0, 1.0, -1.0)
        if not hasattr(self, "coef_"):
            self.coef_ = np.zeros(blocks[0].shape[1] + 1)
            self.t_ = 0
            self.rng_ = np.random.default_rng(self.rng)
        if len(y) == 0:
            return self
        weights = balanced_weights(y) if self.balanced else None
        k = len(y) if self.batch_size is None else min(self.batch_size, len(y))
        Xa = self._augment(blocks)
        n_iter = self.n_iter if n_iter is None else n_iter
        if n_iter <= 0:
            return self
        batches = np.zeros((0, 0), np.int64)   # the whole set every iteration
        if k < len(y):  # A_t: a random mini-batch of k samples per iteration, drawn in order
            batches = np.stack([self.rng_.choice(len(y), size=k, replace=False) for _ in range(n_iter)])
        self.coef_, total = pegasos_steps(self.coef_, Xa, y, np.ones(len(y)) if weights is None else weights,
                                          batches, n_iter, self.t_ + 1,
                                          0 if self.max_t is None else int(self.max_t), float(self.lam))
        self.t_ += n_iter
        self.avg_coef_ = total / n_iter
        return self

    def fit(self, X: np.ndarray, y: np.ndarray) -> "PegasosSVM":
        """Train from scratch (forget any previous ``w``)."""
        for name in ("coef_", "t_", "rng_", "avg_coef_"):
            if hasattr(self, name):
                delattr(self, name)
        return self.partial_fit(X, y)

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Signed scores ``<w, [x, bias_scale]>``, ``(K,)``.

        Before any training ``w = 0`` (Pegasos' starting point), so every score is 0:
        a model that has not seen both classes yet has no opinion, and says so.
        """
        X = np.asarray(X, dtype=float)
        if not hasattr(self, "coef_"):
            return np.zeros(len(X))
        w = self.avg_coef_ if self.average and hasattr(self, "avg_coef_") else self.coef_
        return X @ w[:-1] + self.bias_scale * w[-1]

    def objective(self, X: np.ndarray, y: np.ndarray) -> float:
        """The (class-weighted) SVM objective of the current ``w`` on ``(X, y)``."""
        y = np.where(np.asarray(y) > 0, 1.0, -1.0)
        return svm_objective(self.coef_, self._augment([np.asarray(X)]), y, self.lam,
                             balanced_weights(y) if self.balanced else None)


# Load the compiled kernel at import, not inside the first tracked frame (see vidtrack.measure.slic).
pegasos_steps(np.zeros(2), np.zeros((2, 2)), np.ones(2), np.ones(2), np.zeros((1, 1), np.int64), 1, 1, 0, 1.0)
