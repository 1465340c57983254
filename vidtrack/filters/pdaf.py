"""Probabilistic Data Association Filter (PDAF) on the Kalman functions.

Bar-Shalom & Tse (1975); Bar-Shalom, Daum & Huang, "The probabilistic data
association filter", IEEE Control Systems 2009.  One target in clutter: every
detection inside the validation gate ``nu' S^-1 nu <= gamma`` gets the
association probability::

    L_i    = P_D N(nu_i; 0, S) / lambda
    beta_i = L_i / (1 - P_D P_G + sum_j L_j),  beta_0 = (1 - P_D P_G) / (...)

and the update uses the combined innovation ``nu = sum_i beta_i nu_i``::

    x = x + K nu
    P = beta_0 P + (1 - beta_0) P_c + K (sum_i beta_i nu_i nu_i' - nu nu') K'

with ``P_c`` the single-measurement posterior covariance of
:func:`vidtrack.filters.kalman.kf_update`.  Used as the comparator of the
channel-based tracking detections experiment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kalman import kf_predict, kf_update


@dataclass(frozen=True)
class PDAFUpdate:
    x: np.ndarray
    P: np.ndarray
    beta0: float
    gated: int


def pdaf_update(x: np.ndarray, P: np.ndarray, detections: np.ndarray, H: np.ndarray, R: np.ndarray, *,
                p_detect: float = 0.9, clutter_density: float = 1e-4, gate: float = 9.21,
                p_gate: float = 0.99) -> PDAFUpdate:
    """PDAF update of ``(x, P)`` with unassociated ``detections`` ``(N, m)`` (see the module docstring)."""
    detections = np.asarray(detections, float).reshape(-1, H.shape[0])
    single = kf_update(x, P, H @ x, H, R)  # P_c and S (the measurement value does not matter here)
    S = single.S
    if len(detections) == 0:
        return PDAFUpdate(x, P, 1.0, 0)
    nu = detections - H @ x
    S_inv = np.linalg.inv(S)
    d2 = np.einsum("ni,ij,nj->n", nu, S_inv, nu)
    inside = d2 <= gate
    if not inside.any():
        return PDAFUpdate(x, P, 1.0, 0)
    nu = nu[inside]
    norm = 1.0 / np.sqrt(np.linalg.det(2 * np.pi * S))
    L = p_detect * norm * np.exp(-0.5 * d2[inside]) / clutter_density
    denom = 1.0 - p_detect * p_gate + L.sum()
    beta = L / denom
    beta0 = (1.0 - p_detect * p_gate) / denom
    K = P @ H.T @ S_inv
    nu_c = beta @ nu
    x_post = x + K @ nu_c
    spread = (beta[:, None] * nu).T @ nu - np.outer(nu_c, nu_c)
    P_post = beta0 * P + (1.0 - beta0) * single.P + K @ spread @ K.T
    return PDAFUpdate(x_post, 0.5 * (P_post + P_post.T), float(beta0), int(inside.sum()))


class PDAF:
    """Thin state holder: ``predict`` with :func:`kf_predict`, ``update`` with :func:`pdaf_update`."""

    def __init__(self, F, Q, H, R, *, p_detect: float = 0.9, clutter_density: float = 1e-4, gate: float = 9.21) -> None:
        self.F, self.Q, self.H, self.R = (np.asarray(a, float) for a in (F, Q, H, R))
        self.p_detect = p_detect
        self.clutter_density = clutter_density
        self.gate = gate

    def initialize(self, x0, P0) -> None:
        self.x_ = np.asarray(x0, float).copy()
        self.P_ = np.asarray(P0, float).copy()

    def predict(self) -> np.ndarray:
        self.x_, self.P_ = kf_predict(self.x_, self.P_, self.F, self.Q)
        return self.x_

    def update(self, detections) -> PDAFUpdate:
        result = pdaf_update(self.x_, self.P_, detections, self.H, self.R, p_detect=self.p_detect,
                             clutter_density=self.clutter_density, gate=self.gate)
        self.x_, self.P_ = result.x, result.P
        return result
