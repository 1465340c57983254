"""Extended Kalman filter: nonlinear models linearised around the estimate.

Model::

    x_k = f_k(x_{k-1}) + v,  v ~ N(0, Q)      F_k = df/dx at x_{k-1|k-1}
    z_k = h(x_k) + n,        n ~ N(0, R)      H_k = dh/dx at x_{k|k-1}

Built on :func:`vidtrack.filters.kalman.kf_predict` (covariance propagation
with the Jacobian; the mean goes through ``f``) and
:func:`vidtrack.filters.kalman.kf_update` (fed the pseudo-measurement
``z - h(x) + H x`` so its innovation is ``z - h(x)``).  Used as the EKF
comparator of Carlin's experiment in the Channel-Based Tracking paper.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .kalman import KalmanUpdate, kf_predict, kf_update

Fn = Callable[[np.ndarray], np.ndarray]


def ekf_predict(x: np.ndarray, P: np.ndarray, f: Fn, jacobian: Fn, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x = f(x)``, ``P = F P F' + Q`` with ``F = jacobian(x)``."""
    F = np.atleast_2d(jacobian(x))
    _, P = kf_predict(x, P, F, Q)
    return np.atleast_1d(np.asarray(f(x), dtype=float)), P


def ekf_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, h: Fn, jacobian: Fn, R: np.ndarray) -> KalmanUpdate:
    """Linearised update: innovation ``z - h(x)``, ``H = jacobian(x)``."""
    H = np.atleast_2d(jacobian(x))
    pseudo = np.atleast_1d(z) - np.atleast_1d(h(x)) + H @ x  # so that z' - H x = z - h(x)
    return kf_update(x, P, pseudo, H, R)


class ExtendedKalmanFilter:
    """Thin state holder over :func:`ekf_predict` / :func:`ekf_update`.

    ``f``, ``f_jacobian`` may take a second argument ``k`` (time index),
    passed positionally to :meth:`predict` (``ekf.predict(k)``); ``h``,
    ``h_jacobian`` are time invariant.
    """

    def __init__(self, f: Callable, f_jacobian: Callable, h: Fn, h_jacobian: Fn, Q, R) -> None:
        self.f = f
        self.f_jacobian = f_jacobian
        self.h = h
        self.h_jacobian = h_jacobian
        self.Q = np.atleast_2d(np.asarray(Q, float))
        self.R = np.atleast_2d(np.asarray(R, float))

    def initialize(self, x0, P0) -> None:
        self.x_ = np.atleast_1d(np.asarray(x0, float)).copy()
        self.P_ = np.atleast_2d(np.asarray(P0, float)).copy()

    def predict(self, *args) -> np.ndarray:
        self.x_, self.P_ = ekf_predict(self.x_, self.P_, lambda x: self.f(x, *args),
                                       lambda x: self.f_jacobian(x, *args), self.Q)
        return self.x_

    def update(self, z) -> KalmanUpdate:
        result = ekf_update(self.x_, self.P_, z, self.h, self.h_jacobian, self.R)
        self.x_, self.P_ = result.x, result.P
        return result
