"""Linear epsilon-SVR rows of a transition matrix, with the two-step normalisation.

Salti & Di Stefano, *On-line Support Vector Regression of the Transition
Model for the Kalman Filter*, sections 6.1-6.2.  One linear SVR without bias
regresses component ``i`` of the state at ``k`` from the whole state at
``k - 1`` over a sliding window of ``W`` pairs.

Two-step normalisation (eqs. 11-13).  Every input component ``p`` and the
output ``q`` are first centred on the window's mid-range, ``p_bar = p -
(p_max + p_min) / 2`` (eq. 11), then scaled to ``[-1, 1]``, ``p_tilde = 2
p_bar / (p_bar_max - p_bar_min)`` (eq. 12).  The SVR learns ``q_tilde = w .
p_tilde`` and the unnormalised linear row is (eq. 13)::

    q_bar = sum_j  (q_range / p_range_j) w_j  p_bar_j

so that, with the centres ``c_in`` (inputs) and ``c_out`` (output), the
prediction in the filter's own coordinates is ``q = c_out + F_i . (p -
c_in)`` -- a translation of the state-space origin, which leaves the Kalman
covariance recursion untouched.

Uncertainty (section 6.2, after Lin & Weng, *Simple Probabilistic
Predictions for Support Vector Regression*): the variance of the
regression is the mean squared k-fold cross-validation residual, in
unnormalised units (a Gaussian fit to the residuals, without the
Gaussian/Laplace test).

The solver is scikit-learn's :class:`~sklearn.svm.LinearSVR` (liblinear,
epsilon-insensitive loss, ``fit_intercept=False``) with folds from
:class:`~sklearn.model_selection.KFold`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: Ranges at or below this (relative to the data's magnitude) count as constant.
_TINY = 1e-12


@dataclass(frozen=True)
class WindowScaling:
    """Two-step normalisation of one training window (eqs. 11-12).

    ``center_in (n,)``, ``half_range_in (n,)`` for the inputs and
    ``center_out``, ``half_range_out`` for the output: ``p_tilde = (p -
    center) / half_range``.  A constant component gets ``half_range = 1``
    (its normalised values are all 0 and its weight is irrelevant).
    """

    center_in: np.ndarray
    half_range_in: np.ndarray
    center_out: float
    half_range_out: float

    def inputs(self, X: np.ndarray) -> np.ndarray:
        """Normalised inputs ``(X - c_in) / s_in``."""
        return (np.asarray(X, float) - self.center_in) / self.half_range_in

    def outputs(self, y: np.ndarray) -> np.ndarray:
        """Normalised outputs ``(y - c_out) / s_out``."""
        return (np.asarray(y, float) - self.center_out) / self.half_range_out

    def unnormalised_row(self, w: np.ndarray) -> np.ndarray:
        """Eq. 13: ``F_ij = (q_range / p_range_j) w_j`` acting on centred inputs."""
        return self.half_range_out * np.asarray(w, float) / self.half_range_in


def _center_and_half_range(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hi, lo = values.max(axis=0), values.min(axis=0)
    center = 0.5 * (hi + lo)  # eq. 11: mid-range of the window
    half = 0.5 * (hi - lo)  # eq. 12: centred data span [-half, half]
    tiny = _TINY * np.maximum(1.0, np.abs(center))
    return center, np.where(half > tiny, half, 1.0)


def window_scaling(X: np.ndarray, y: np.ndarray) -> WindowScaling:
    """Mid-range centres and half ranges of a window ``X (W, n)``, ``y (W,)``."""
    c_in, s_in = _center_and_half_range(np.asarray(X, float))
    c_out, s_out = _center_and_half_range(np.asarray(y, float)[:, None])
    return WindowScaling(c_in, s_in, float(c_out[0]), float(s_out[0]))


@lru_cache(maxsize=32)
def _folds(n_samples: int, n_folds: int) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """Contiguous k-fold (train, test) index pairs, cached per window size."""
    k = int(min(max(n_folds, 2), n_samples))
    from sklearn.model_selection import KFold   # loaded on first use, as in fit_svr

    return tuple(KFold(n_splits=k).split(np.zeros((n_samples, 1))))


def fit_linear_svr(X: np.ndarray, y: np.ndarray, *, C: float, epsilon: float,
                   max_iter: int = 2000, tol: float = 1e-4) -> np.ndarray:
    """Weights ``w`` of a linear epsilon-SVR without bias (eq. 6 with ``b = 0``).

    ``min 1/2 |w|^2 + C sum max(0, |y_i - w . x_i| - epsilon)`` solved by
    liblinear's dual coordinate descent.  Convergence warnings are silenced
    (a few iterations short on a 10-sample window change nothing that
    matters here).  liblinear's coordinate order is seeded, so the result is
    deterministic.
    """
    import sklearn   # loaded when an SVR is first trained, not with every vidtrack command
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.svm import LinearSVR

    model = LinearSVR(C=C, epsilon=epsilon, fit_intercept=False, loss="epsilon_insensitive",
                      dual=True, max_iter=max_iter, tol=tol, random_state=0)
    with warnings.catch_warnings(), sklearn.config_context(assume_finite=True, skip_parameter_validation=True):
        warnings.simplefilter("ignore", ConvergenceWarning)
        model.fit(X, y)
    return np.asarray(model.coef_, float).ravel()


@dataclass(frozen=True)
class SVRRow:
    """One learned row: ``q = offset + row . p`` with its residual variance.

    ``row (n,)`` is eq. 13's linear row (the entries of ``F``), ``offset =
    c_out - row . c_in`` the origin translation, ``variance`` the mean
    squared cross-validation residual (the ``Q`` diagonal entry before the
    floor), ``weights`` the SVR's normalised weights.
    """

    row: np.ndarray
    offset: float
    variance: float
    weights: np.ndarray


def learn_row(X: np.ndarray, y: np.ndarray, *, C: float, epsilon: float, n_folds: int = 5) -> SVRRow:
    """Learn one transition row from a window (sections 6.1-6.2).

    Parameters
    ----------
    X
        ``(W, n)`` states at ``k - 1``.
    y
        ``(W,)`` component ``i`` of the states at ``k``.
    C, epsilon
        SVR parameters; ``epsilon`` is in normalised units (outputs in ``[-1, 1]``).
    n_folds
        Folds of the cross-validation estimating the residual variance.
    """
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    scaling = window_scaling(X, y)
    Xt, yt = scaling.inputs(X), scaling.outputs(y)
    w = fit_linear_svr(Xt, yt, C=C, epsilon=epsilon)
    residuals = np.empty(len(y))
    for train, test in _folds(len(y), n_folds):
        w_fold = fit_linear_svr(Xt[train], yt[train], C=C, epsilon=epsilon)
        residuals[test] = (yt[test] - Xt[test] @ w_fold) * scaling.half_range_out  # back to state units
    row = scaling.unnormalised_row(w)
    offset = scaling.center_out - float(row @ scaling.center_in)
    return SVRRow(row, offset, float(np.mean(residuals ** 2)), w)


def learn_transition(X_prev: np.ndarray, X_next: np.ndarray, *, C: float, epsilon: float,
                     n_folds: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All rows: ``(F (n, n), offset (n,), variances (n,))`` with ``x_k ~ F x_{k-1} + offset``."""
    X_prev = np.asarray(X_prev, float)
    X_next = np.asarray(X_next, float)
    rows = [learn_row(X_prev, X_next[:, i], C=C, epsilon=epsilon, n_folds=n_folds)
            for i in range(X_next.shape[1])]
    F = np.array([r.row for r in rows])
    return F, np.array([r.offset for r in rows]), np.array([r.variance for r in rows])


def process_noise_floor(H: np.ndarray, R: np.ndarray, fraction: float = 0.1) -> np.ndarray:
    """Lower bound of each ``Q_ii``: ``fraction`` of the matching ``R`` entry (section 6.2).

    The measured components (through ``H``) take ``fraction * (H' R H)_ii``;
    unmeasured ones (e.g. velocities when only positions are measured) take
    ``fraction`` of the mean measured variance.
    """
    H = np.atleast_2d(np.asarray(H, float))
    R = np.atleast_2d(np.asarray(R, float))
    mapped = np.diag(H.T @ R @ H).copy()
    weights = np.diag(H.T @ H)
    measured = weights > 0
    mapped[measured] /= weights[measured] ** 2
    mapped[~measured] = float(np.mean(np.diag(R)))
    return fraction * mapped
