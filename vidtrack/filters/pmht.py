"""Probabilistic Multi-Hypothesis Tracker (PMHT) over a sliding batch, on the Kalman functions.

Streit & Luginbuhl, *Probabilistic Multi-Hypothesis Tracking* (NUWC-NPT
Technical Report 10,428, 1995).  ``M`` targets with linear-Gaussian models
``x_t = F x_{t-1} + w``, ``z = H x + v`` and unassociated detections; the
assignment of each detection to a target (or to clutter, target 0) is a
hidden variable, independent across detections, with prior probabilities
``pi_m``.  EM over a batch of frames ``t = 1..T``:

* E-step, posterior assignment weights of detection ``r`` of frame ``t``::

      w_tr^m = pi_m N(z_tr; H x_t^m, R) / (pi_0 / A + sum_l pi_l N(z_tr; H x_t^l, R))

  with clutter uniform over the observed area ``A``;
* M-step, per target, a Kalman smoother on *synthetic* measurements::

      z~_t^m = sum_r w_tr^m z_tr / W_t^m,   R~_t^m = R / W_t^m,   W_t^m = sum_r w_tr^m

  (frames with ``W_t^m`` ~ 0 are predictions only).

:func:`pmht_batch` runs a few EM iterations on one batch; :class:`PMHT`
slides a window of ``window`` frames: each new frame is appended (its states
initialised by prediction), EM runs over the window started from the fixed
estimate of the frame before it, and the frame leaving the window keeps its
last smoothed estimate.  Track management (birth, deletion) is not part of
it: the number of targets and their first states are given.  The Kalman
prediction, update and the RTS smoother reuse :mod:`vidtrack.filters.kalman`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kalman import kf_predict, kf_update


def rts_smoother(x0: np.ndarray, P0: np.ndarray, F: np.ndarray, Q: np.ndarray, H: np.ndarray,
                 zs: list[np.ndarray | None], Rs: list[np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    """Kalman filter forward from ``(x0, P0)`` (the state *before* the first frame), Rauch-Tung-Striebel back.

    ``zs[t]`` / ``Rs[t]``: the measurement and its covariance of frame ``t``
    (None: prediction only).  Returns the smoothed means ``(T, n)`` and
    covariances ``(T, n, n)``:
    ``C = P_f F' P_p^-1``; ``x_s = x_f + C (x_s' - x_p')``; ``P_s = P_f + C (P_s' - P_p') C'``.
    """
    T, n = len(zs), len(x0)
    xp, Pp = np.empty((T, n)), np.empty((T, n, n))
    xf, Pf = np.empty((T, n)), np.empty((T, n, n))
    x, P = np.asarray(x0, float), np.asarray(P0, float)
    for t in range(T):
        x, P = kf_predict(x, P, F, Q)  # x = F x, P = F P F' + Q
        xp[t], Pp[t] = x, P
        if zs[t] is not None:
            u = kf_update(x, P, zs[t], H, Rs[t])
            x, P = u.x, u.P
        xf[t], Pf[t] = x, P
    xs, Ps = xf.copy(), Pf.copy()
    for t in range(T - 2, -1, -1):
        C = np.linalg.solve(Pp[t + 1].T, (Pf[t] @ F.T).T).T  # C = P_f F' P_p^-1
        xs[t] = xf[t] + C @ (xs[t + 1] - xp[t + 1])
        Ps[t] = Pf[t] + C @ (Ps[t + 1] - Pp[t + 1]) @ C.T
        Ps[t] = 0.5 * (Ps[t] + Ps[t].T)
    return xs, Ps


def assignment_weights(detections: np.ndarray, means: np.ndarray, S: np.ndarray, priors: np.ndarray,
                       clutter_weight: float) -> np.ndarray:
    """E-step of one frame: ``w[r, m]`` for detections ``(N, d)``, predicted measurements ``(M, d)``.

    ``S`` is the measurement covariance ``R``; ``clutter_weight = pi_0 / A`` (clutter uniform over area ``A``).
    """
    if len(detections) == 0:
        return np.zeros((0, len(means)))
    nu = detections[:, None, :] - means[None, :, :]  # (N, M, d)
    S_inv = np.linalg.inv(S)
    d2 = np.einsum("nmi,ij,nmj->nm", nu, S_inv, nu)
    norm = 1.0 / np.sqrt(np.linalg.det(2.0 * np.pi * S))
    L = priors[None, :] * norm * np.exp(-0.5 * d2)
    return L / (clutter_weight + L.sum(axis=1, keepdims=True))


def synthetic_measurement(detections: np.ndarray, w: np.ndarray, R: np.ndarray,
                          min_weight: float = 1e-6) -> tuple[np.ndarray | None, np.ndarray | None]:
    """M-step input of one target and frame: ``z~ = sum_r w_r z_r / W``, ``R~ = R / W`` (None if ``W`` ~ 0)."""
    W = float(w.sum())
    if W < min_weight:
        return None, None
    return (w @ detections) / W, R / W


def pmht_batch(x0s: np.ndarray, P0s: np.ndarray, F: np.ndarray, Q: np.ndarray, H: np.ndarray, R: np.ndarray,
               frames: list[np.ndarray], init: np.ndarray, *, priors: np.ndarray, clutter_weight: float,
               iterations: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """EM over one batch (see the module docstring).

    Parameters
    ----------
    x0s, P0s
        Per target, the (fixed) state before the batch ``(M, n)``, ``(M, n, n)``.
    frames
        The batch's detections, ``(N_t, d)`` per frame.
    init
        Initial state estimates ``(M, T, n)`` of the batch.
    priors
        Assignment priors ``pi_m`` of the targets ``(M,)``.
    clutter_weight
        ``pi_0 / A``.

    Returns
    -------
    Smoothed means ``(M, T, n)`` and covariances ``(M, T, n, n)``.
    """
    M, T = init.shape[0], len(frames)
    xs = init.copy()
    Ps = np.zeros((M, T, F.shape[0], F.shape[0]))
    for _ in range(iterations):
        weights = [assignment_weights(frames[t], xs[:, t] @ H.T, R, priors, clutter_weight) for t in range(T)]
        for m in range(M):
            synth = [synthetic_measurement(frames[t], weights[t][:, m], R) for t in range(T)]
            xs[m], Ps[m] = rts_smoother(x0s[m], P0s[m], F, Q, H, [s[0] for s in synth], [s[1] for s in synth])
    return xs, Ps


@dataclass
class PMHT:
    """Sliding-batch PMHT of ``M`` targets sharing one Kalman model ``(F, Q, H, R)``.

    Parameters
    ----------
    F, Q, H, R
        The targets' motion and measurement model.
    clutter_density
        Clutter detections per unit area (``lambda``).
    p_detect
        Expected detections per target and frame; with the expected clutter
        count it sets the assignment priors ``pi``.
    area
        Area of the observed region (expected clutter count ``lambda * area``).
    window
        Frames per batch.
    iterations
        EM iterations per batch.
    """

    F: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray
    clutter_density: float = 1e-4
    p_detect: float = 0.9
    area: float = 1.0
    window: int = 5
    iterations: int = 5

    def initialize(self, x0s: np.ndarray, P0s: np.ndarray) -> None:
        """Start the ``M`` tracks at ``x0s`` ``(M, n)`` with covariances ``P0s`` ``(M, n, n)``."""
        self.x_ = np.asarray(x0s, float).copy()
        self.P_ = np.asarray(P0s, float).copy()
        self.anchor_ = (self.x_.copy(), self.P_.copy())  # state before the window
        self.frames_: list[np.ndarray] = []
        self.batch_ = np.zeros((len(self.x_), 0, self.x_.shape[1]))
        self.batch_P_ = np.zeros((len(self.x_), 0, self.x_.shape[1], self.x_.shape[1]))

    def _priors(self) -> tuple[np.ndarray, float]:
        M = len(self.x_)
        expected = np.append(np.full(M, self.p_detect), self.clutter_density * self.area)
        pi = expected / expected.sum()
        return pi[:M], float(pi[M] / max(self.area, 1e-300))  # clutter: pi_0 times the uniform pdf 1 / A

    def step(self, detections: np.ndarray) -> np.ndarray:
        """Add one frame of detections ``(N, d)``, run EM on the window; returns the current states ``(M, n)``."""
        detections = np.asarray(detections, float).reshape(-1, self.H.shape[0])
        if len(self.frames_) == self.window:  # the oldest frame leaves: its estimate becomes the anchor
            self.anchor_ = (self.batch_[:, 0].copy(), self.batch_P_[:, 0].copy())
            self.frames_.pop(0)
            self.batch_, self.batch_P_ = self.batch_[:, 1:], self.batch_P_[:, 1:]
        self.frames_.append(detections)
        last = self.batch_[:, -1] if self.batch_.shape[1] else self.anchor_[0]
        init = np.concatenate([self.batch_, (last @ self.F.T)[:, None, :]], axis=1)
        priors, clutter_weight = self._priors()
        self.batch_, self.batch_P_ = pmht_batch(self.anchor_[0], self.anchor_[1], self.F, self.Q, self.H, self.R,
                                                self.frames_, init, priors=priors, clutter_weight=clutter_weight,
                                                iterations=self.iterations)
        self.x_, self.P_ = self.batch_[:, -1].copy(), self.batch_P_[:, -1].copy()
        return self.x_
