"""Support Vector Kalman: a Kalman filter whose ``F`` and ``Q`` are learned online.

Salti & Di Stefano, *On-line Support Vector Regression of the Transition
Model for the Kalman Filter*, Algorithm 1.  Model::

    x_k = F_k x_{k-1} + u_k + nu_k,   nu_k ~ N(0, Q_k),  Q_k diagonal
    z_k = H x_k + eta_k,              eta_k ~ N(0, R_k)

After each update the pair ``(x_{k-1}, x_k)`` of filtered states enters a
sliding window of ``W`` pairs; once full, ``n`` linear SVRs without bias (one
per state component, :func:`vidtrack.learn.svr.learn_transition`) give the
rows of ``F_{k+1}`` through the two-step normalisation (eqs. 11-13),
``u_{k+1}`` the translation of the origin that normalisation implies, and
``Q_{k+1}[i, i]`` the mean squared k-fold cross-validation residual of SVR
``i`` (section 6.2), floored at ``q_floor`` (10 %) of the matching ``R``
entry so the filter keeps listening to measurements.  Until the window is
full (the bootstrap of Algorithm 1) the filter runs the default model
``(F0, Q0)``.

:class:`SupportVectorKalman` quacks like
:class:`vidtrack.filters.kalman.KalmanFilter` (``initialize``, ``predict``,
``update``, ``x_``, ``P_``), so :class:`vidtrack.filters.box.CentreFilter`
runs it on video; ``scalars_`` holds ``F_ij`` and ``Q_ii`` for plotting and
:class:`SVKCentreFilter` copies them into the box estimate's scalars.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from ..learn.svr import learn_transition, process_noise_floor
from ..types import Estimate, Measurement
from .box import CentreFilter
from .kalman import KalmanUpdate, kf_predict, kf_update


def svk_predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray,
                u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Prediction with the learned model: ``x = F x + u``, ``P = F P F' + Q``."""
    x, P = kf_predict(x, P, F, Q)
    return x + u, P


def learned_process_noise(variances: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """``Q = diag(max(cv_variance_i, floor_i))`` (section 6.2)."""
    return np.diag(np.maximum(np.asarray(variances, float), np.asarray(floor, float)))


class SupportVectorKalman:
    """Kalman filter with an online SVR-learned transition model (see module docstring).

    Parameters
    ----------
    H, R
        Measurement matrix ``(m, n)`` and default measurement covariance ``(m, m)``.
    F0, Q0
        Bootstrap transition model used until ``window`` pairs are collected.
    C
        SVR regularisation weight (the paper: ``2**-10`` on linear motion, 2 on non-linear).
    epsilon
        SVR insensitivity, in normalised units (outputs scaled to ``[-1, 1]``).
    window
        ``W``, the number of state pairs in the sliding training window.
    n_folds
        Folds of the cross-validation estimating ``Q``.
    q_floor
        ``Q_ii`` never goes below this fraction of the matching ``R`` entry.
    """

    def __init__(self, H: np.ndarray, R: np.ndarray, F0: np.ndarray, Q0: np.ndarray, *,
                 C: float = 2.0 ** -10, epsilon: float = 0.1, window: int = 10, n_folds: int = 5,
                 q_floor: float = 0.1) -> None:
        self.H = np.asarray(H, dtype=float)
        self.R = np.asarray(R, dtype=float)
        self.F0 = np.asarray(F0, dtype=float)
        self.Q0 = np.asarray(Q0, dtype=float)
        self.C = C
        self.epsilon = epsilon
        self.window = window
        self.n_folds = n_folds
        self.q_floor = q_floor

    def initialize(self, x0: np.ndarray, P0: np.ndarray) -> None:
        """Set ``(x, P)``, restore the bootstrap model and empty the window."""
        self.x_ = np.asarray(x0, dtype=float).copy()
        self.P_ = np.asarray(P0, dtype=float).copy()
        n = len(self.x_)
        self.F_ = self.F0.copy()
        self.Q_ = self.Q0.copy()
        self.u_ = np.zeros(n)
        self.cv_variance_ = np.full(n, np.nan)
        self.inputs_: deque[np.ndarray] = deque(maxlen=self.window)
        self.outputs_: deque[np.ndarray] = deque(maxlen=self.window)
        self.previous_: np.ndarray | None = None
        self.learned_ = False

    @property
    def scalars_(self) -> dict[str, float]:
        """Learned ``F_ij`` and ``Q_ii`` as named scalars (for the Rerun sink)."""
        n = len(self.x_)
        out = {f"F_{i}{j}": float(self.F_[i, j]) for i in range(n) for j in range(n)}
        out.update({f"Q_{i}{i}": float(self.Q_[i, i]) for i in range(n)})
        return out

    def predict(self) -> tuple[np.ndarray, np.ndarray]:
        """``x = F x + u``, ``P = F P F' + Q``; remembers ``x_{k-1}`` for learning."""
        self.previous_ = self.x_.copy()
        self.x_, self.P_ = svk_predict(self.x_, self.P_, self.F_, self.Q_, self.u_)
        return self.x_, self.P_

    def update(self, z: np.ndarray, R: np.ndarray | None = None) -> KalmanUpdate:
        """Kalman update, then add ``(x_{k-1}, x_k)`` to the window and relearn ``F``, ``Q``."""
        R = self.R if R is None else np.asarray(R, dtype=float)
        result = kf_update(self.x_, self.P_, z, self.H, R)
        self.x_, self.P_ = result.x, result.P
        if self.previous_ is not None:
            self.inputs_.append(self.previous_)
            self.outputs_.append(self.x_.copy())
            self.previous_ = None
            if len(self.inputs_) == self.window:
                self._learn(R)
        return result

    def _learn(self, R: np.ndarray) -> None:
        """Algorithm 1's main loop: train the SVRs, set ``F_{k+1}``, ``u_{k+1}``, ``Q_{k+1}``."""
        F, u, variances = learn_transition(np.array(self.inputs_), np.array(self.outputs_),
                                           C=self.C, epsilon=self.epsilon, n_folds=self.n_folds)
        if not (np.all(np.isfinite(F)) and np.all(np.isfinite(u)) and np.all(np.isfinite(variances))):
            return  # a degenerate window (e.g. non-finite states): keep the current model
        self.F_, self.u_, self.cv_variance_ = F, u, variances
        self.Q_ = learned_process_noise(variances, process_noise_floor(self.H, R, self.q_floor))
        self.learned_ = True


class SVKCentreFilter(CentreFilter):
    """:class:`CentreFilter` over a :class:`SupportVectorKalman` core that also reports ``F_ij``, ``Q_ii``.

    The core's learned model goes into ``Estimate.scalars`` (``F_00`` ...
    ``F_33``, ``Q_00`` ... ``Q_33`` for the state ``[p_x, v_x, p_y, v_y]``),
    which the Rerun sink logs under ``filter/<name>``.
    """

    def update(self, measurement: Measurement | None) -> Estimate:
        estimate = super().update(measurement)
        scalars = {**estimate.scalars, **self.core_.scalars_}
        self.estimate_ = replace(estimate, scalars=scalars)
        return self.estimate_
