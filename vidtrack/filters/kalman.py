"""Linear Kalman filter: pure predict/update functions, motion models, and a thin class.

Model (Kalman, 1960)::

    x_k = F x_{k-1} + w,  w ~ N(0, Q)
    z_k = H x_k + v,      v ~ N(0, R)

The update uses the Joseph form ``P = (I - K H) P (I - K H)' + K R K'``, which
stays symmetric positive semi-definite under round-off.

Motion models (per axis, Bar-Shalom, Li & Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, ch. 6): drift / constant position
(``"dr"``), constant velocity (``"cv"``) and constant acceleration (``"ca"``),
each driven by discrete white noise on its highest derivative.  The same
models are used by the Kalman trackers on video, the IMM, the Support Vector
Kalman comparisons and the MIL filter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

MOTION_ORDERS = {"dr": 1, "cv": 2, "ca": 3}


@dataclass(frozen=True)
class KalmanUpdate:
    """Result of :func:`kf_update`.

    ``x``, ``P`` posterior; ``innovation`` ``y = z - H x_prior``; ``S`` its
    covariance; ``log_likelihood`` ``log N(y; 0, S)``.
    """

    x: np.ndarray
    P: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    log_likelihood: float


def kf_predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kalman prediction: ``x = F x``, ``P = F P F' + Q``."""
    x = F @ x
    P = F @ P @ F.T + Q
    return x, 0.5 * (P + P.T)


def kf_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray) -> KalmanUpdate:
    """Kalman update in Joseph form.

    ``y = z - H x``; ``S = H P H' + R``; ``K = P H' S^-1``;
    ``x = x + K y``; ``P = (I - K H) P (I - K H)' + K R K'``.
    """
    y = np.asarray(z, dtype=float) - H @ x
    S = H @ P @ H.T + R
    S = 0.5 * (S + S.T)
    K = np.linalg.solve(S, H @ P).T  # K = P H' S^-1 (S, P symmetric)
    x_post = x + K @ y
    I_KH = np.eye(len(x)) - K @ H
    P_post = I_KH @ P @ I_KH.T + K @ R @ K.T  # Joseph form
    P_post = 0.5 * (P_post + P_post.T)
    sign, logdet = np.linalg.slogdet(S)
    loglik = -0.5 * (float(y @ np.linalg.solve(S, y)) + logdet + len(y) * np.log(2.0 * np.pi))
    return KalmanUpdate(x_post, P_post, y, S, float(loglik))


def axis_transition(model: str, dt: float, order: int | None = None) -> np.ndarray:
    """Per-axis transition matrix of ``model`` in a state ``[p, v, a][:order]``.

    ``order`` defaults to the model's own (dr 1, cv 2, ca 3).  A larger order
    embeds the model with zero rows for the derivatives it does not carry
    (the usual embedding for an IMM mixing models of different order).
    """
    native = MOTION_ORDERS[model]
    order = native if order is None else order
    if order < native:
        raise ValueError(f"order {order} too small for model {model!r}")
    full = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    F = np.zeros((order, order))
    F[:native, :native] = full[:native, :native]
    return F


def axis_process_noise(model: str, dt: float, q: float, order: int | None = None) -> np.ndarray:
    """Discrete white-noise process covariance ``Q = q G G'`` of ``model``.

    Bar-Shalom et al. (2001), section 6.3: drift, a random walk with
    velocity noise, ``G = [dt]``; constant velocity, discrete white noise
    acceleration (DWNA), ``G = [dt^2/2, dt]``; constant acceleration,
    discrete Wiener process acceleration (DWPA), ``G = [dt^2/2, dt, 1]``.
    ``q`` is the variance of the driving noise.
    """
    native = MOTION_ORDERS[model]
    order = native if order is None else order
    gains = {"dr": np.array([dt]), "cv": np.array([0.5 * dt * dt, dt]),
             "ca": np.array([0.5 * dt * dt, dt, 1.0])}[model]
    Q = np.zeros((order, order))
    Q[:native, :native] = q * np.outer(gains, gains)
    return Q


def motion_model(model: str, *, dt: float = 1.0, q: float = 1.0, n_axes: int = 2,
                 order: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, Q, H)`` for ``n_axes`` independent axes, position measured.

    The state is axis-major: ``[p_x, v_x, a_x, p_y, v_y, a_y][...]`` truncated
    to ``order`` entries per axis; ``H`` picks each axis' position.
    """
    order = MOTION_ORDERS[model] if order is None else order
    F = block_diag(*[axis_transition(model, dt, order)] * n_axes)
    Q = block_diag(*[axis_process_noise(model, dt, q, order)] * n_axes)
    H = np.zeros((n_axes, order * n_axes))
    H[np.arange(n_axes), np.arange(n_axes) * order] = 1.0
    return F, Q, H


class KalmanFilter:
    """A linear Kalman filter holding ``(x, P)`` and the model ``(F, Q, H, R)``.

    A thin state holder over :func:`kf_predict` and :func:`kf_update`
    (FilterPy style); model matrices are plain attributes, so a learner may
    replace them between steps.
    """

    def __init__(self, F: np.ndarray, Q: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        self.F = np.asarray(F, dtype=float)
        self.Q = np.asarray(Q, dtype=float)
        self.H = np.asarray(H, dtype=float)
        self.R = np.asarray(R, dtype=float)

    def initialize(self, x0: np.ndarray, P0: np.ndarray) -> None:
        """Set the state mean and covariance."""
        self.x_ = np.asarray(x0, dtype=float).copy()
        self.P_ = np.asarray(P0, dtype=float).copy()

    def predict(self) -> tuple[np.ndarray, np.ndarray]:
        """Propagate ``(x, P)`` one step; return the prior."""
        self.x_, self.P_ = kf_predict(self.x_, self.P_, self.F, self.Q)
        return self.x_, self.P_

    def update(self, z: np.ndarray, R: np.ndarray | None = None) -> KalmanUpdate:
        """Fold in measurement ``z`` (covariance ``R`` or the filter's own)."""
        result = kf_update(self.x_, self.P_, z, self.H, self.R if R is None else R)
        self.x_, self.P_ = result.x, result.P
        return result


def measured_axis_model(model: str, *, dt: float, q: float, r: float, n_measured: int = 2,
                        order: int | None = None, unmodelled_q: float = 0.0
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(F, Q, H, R)`` of one axis whose first ``n_measured`` derivatives are measured.

    The 1-D setting of Salti & Di Stefano's simulations (On-line Support
    Vector Regression of the Transition Model for the Kalman Filter, sec. 7):
    position and velocity both measured with ``R = r I``, every model tuned
    with ``Q = q I`` on the components it carries ("Q = 1e-2 R" means
    ``q = 1e-2 r``).  ``order`` embeds the model in a larger state (as in an
    IMM); the components the model does not carry get process variance
    ``unmodelled_q`` (0 keeps them at the model's zero rows; a large value
    makes the model agnostic about them).
    """
    native = MOTION_ORDERS[model]
    order = native if order is None else order
    F = axis_transition(model, dt, order)
    Q = np.diag([q] * native + [unmodelled_q] * (order - native))
    H = np.zeros((n_measured, order))
    k = min(n_measured, order)
    H[np.arange(k), np.arange(k)] = 1.0
    return F, Q, H, r * np.eye(n_measured)
