"""The IMM rows of Salti & Di Stefano's Tables 1-3: the IMM and the readings of it that were tried.

Salti & Di Stefano, *On-line Support Vector Regression of the Transition
Model for the Kalman Filter*, compare the Support Vector Kalman with IMMs
(Blom & Bar-Shalom, :mod:`vidtrack.filters.imm`) over a pool of Kalman
models: DR+CV+CA ("IMM CA") and DR+CV ("IMM CV"), position and velocity
measured, the uniform transition probability matrix.  The paper does not say
how models of different order are mixed, nor how the mode probabilities are
computed; :func:`imm` builds every reading used by
:mod:`vidtrack.experiments.svk_tables` and :data:`IMM_VARIANTS` names those
its ``--imm-variants`` table compares.  What each reading gives, and why, is
in ``docs/reproduction.md`` (section "Support Vector Kalman").
"""

from __future__ import annotations

import numpy as np

from ..filters.imm import IMMEstimator, MixedOrderIMM, sticky_transition_matrix, uniform_transition_matrix
from ..filters.kalman import MOTION_ORDERS, KalmanFilter, axis_process_noise, measured_axis_model


class PositionOnlyKalman(KalmanFilter):
    """A Kalman filter that folds in only the position of the ``[p, v]`` measurement.

    The reading of an IMM whose drift model, having no velocity, is given
    the position alone: its likelihood is a 1-D density, the other models'
    2-D ones.
    """

    def update(self, z: np.ndarray, R: np.ndarray | None = None):
        return super().update(np.asarray(z, dtype=float)[:1], None if R is None else np.asarray(R)[:1, :1])


def imm_model(model: str, *, dt: float, q: float, r: float, order: int | None = None, unmodelled_q: float = 0.0,
              q_form: str = "diag", dr_velocity: bool = True, carry: bool = False) -> KalmanFilter:
    """One IMM model: :func:`kalman`, optionally with white-noise ``Q`` or a position-only drift model.

    ``q_form="diag"``: ``Q = q I`` on the components the model carries (as
    the Kalman rows); ``"white-noise"``: Bar-Shalom's discrete white-noise
    ``Q = q G G'`` (:func:`vidtrack.filters.kalman.axis_process_noise`).
    Unmodelled components get ``unmodelled_q`` either way.
    ``dr_velocity=False``: the drift model sees the position measurement only.
    ``carry=True`` (embedded in a larger ``order``): the derivatives the model
    does not carry are kept by identity rows of ``F`` (carried along, unused)
    instead of reset to 0 by zero rows.
    """
    native = MOTION_ORDERS[model]
    position_only = model == "dr" and not dr_velocity
    F, Q, H, R = measured_axis_model(model, dt=dt, q=q, r=r, order=order, unmodelled_q=unmodelled_q,
                                     n_measured=1 if position_only else 2)
    if q_form == "white-noise":
        Q = axis_process_noise(model, dt, q, order)
        Q[native:, native:] += unmodelled_q * np.eye(len(Q) - native)
    elif q_form != "diag":
        raise ValueError(f"q_form must be 'diag' or 'white-noise', got {q_form!r}")
    if carry:
        F[native:, native:] = np.eye(len(F) - native)
    return (PositionOnlyKalman if position_only else KalmanFilter)(F, Q, H, R)


def imm(pool: tuple[str, ...], *, dt: float, q: float, r: float, unmodelled_q: float | str,
        formulation: str = "embedded", pad_var: float = 0.0, stay: float | None = None,
        estimate: str = "combined", likelihood: str = "log", q_form: str = "diag", dr_velocity: bool = True,
        carry: bool = False):
    """IMM over ``pool``, uniform transition probabilities unless ``stay`` is given.

    ``formulation``: ``"embedded"`` -- every model in the common state, its
    unmodelled derivatives with process variance ``unmodelled_q * r`` (the
    default; ``unmodelled_q="q"``: the model's own ``q``, i.e. ``Q = q I``
    on the common state for every model); ``"native-zero"`` -- each model in
    its own state, a lower model's missing derivatives augmented with mean 0
    and variance ``pad_var * r`` when mixed into a higher one;
    ``"native-own"`` -- augmented with the receiving model's own estimate (see
    :func:`vidtrack.filters.imm.mixed_order_mix`).  ``estimate``: the combined
    estimate or the most likely mode's.  ``likelihood``: mode probabilities
    from log-likelihoods or from float64 / float32 densities (which underflow).
    ``q_form``, ``dr_velocity`` and ``carry`` (embedded only): see :func:`imm_model`.
    """
    M = uniform_transition_matrix(len(pool)) if stay is None else sticky_transition_matrix(len(pool), stay)
    opts = {"dt": dt, "q": q, "r": r, "q_form": q_form, "dr_velocity": dr_velocity}
    if formulation == "embedded":
        order = max(MOTION_ORDERS[m] for m in pool)
        uq = q if unmodelled_q == "q" else float(unmodelled_q) * r
        filters = [imm_model(m, order=order, unmodelled_q=uq, carry=carry, **opts) for m in pool]
        if estimate == "combined" and likelihood == "log":
            return IMMEstimator(filters, M)
        # equal sizes: the same mixing as IMMEstimator
        return MixedOrderIMM(filters, M, estimate=estimate, likelihood=likelihood)
    pad = {"native-zero": "zero", "native-own": "own"}[formulation]
    filters = [imm_model(m, **opts) for m in pool]
    return MixedOrderIMM(filters, M, pad=pad, pad_var=pad_var * r, estimate=estimate, likelihood=likelihood)


#: The IMM formulations tried against the paper's IMM rows (``--imm-variants``): name -> options.
IMM_VARIANTS = {
    "embedded, unmodelled var r (default)": {},
    "embedded, unmodelled var 0": {"unmodelled_q": 0.0},
    "embedded, unmodelled var 1e4 r": {"unmodelled_q": 1e4},
    "native, augmented 0 (var 0)": {"formulation": "native-zero", "pad_var": 0.0},
    "native, augmented 0 (var r)": {"formulation": "native-zero", "pad_var": 1.0},
    "native, augmented 0 (var 1e4 r)": {"formulation": "native-zero", "pad_var": 1e4},
    "native, augmented own estimate": {"formulation": "native-own"},
    "embedded r, sticky TPM 0.9": {"stay": 0.9},
    "embedded r, sticky TPM 0.99": {"stay": 0.99},
    "embedded r, most likely mode": {"estimate": "mode"},
    "native 0 (var 0), most likely mode": {"formulation": "native-zero", "estimate": "mode"},
    "float64 lik.: embedded, var r": {"likelihood": "float64"},
    "float64 lik.: embedded, var 0.1 r": {"likelihood": "float64", "unmodelled_q": 0.1},
    "float64 lik.: native 0 (var 0)": {"likelihood": "float64", "formulation": "native-zero"},
    "float64 lik.: native 0 (var r)": {"likelihood": "float64", "formulation": "native-zero", "pad_var": 1.0},
    "float64 lik.: native, own estimate": {"likelihood": "float64", "formulation": "native-own"},
    "float32 lik.: embedded, var r": {"likelihood": "float32"},
    "float32 lik.: native 0 (var 0)": {"likelihood": "float32", "formulation": "native-zero"},
    "float32 lik.: native 0 (var r)": {"likelihood": "float32", "formulation": "native-zero", "pad_var": 1.0},
    "float32 lik.: native, own estimate": {"likelihood": "float32", "formulation": "native-own"},
    "embedded, Q = q I on the common state": {"unmodelled_q": "q"},
    "embedded r, white-noise Q (DWNA/DWPA)": {"q_form": "white-noise"},
    "native 0 (var r), DR sees position only": {"formulation": "native-zero", "pad_var": 1.0, "dr_velocity": False},
    "native 0 (var 0.01 r)": {"formulation": "native-zero", "pad_var": 0.01},
    "native 0 (var 0.1 r)": {"formulation": "native-zero", "pad_var": 0.1},
    "float32 lik.: native 0 (var 0.1 r)": {"likelihood": "float32", "formulation": "native-zero", "pad_var": 0.1},
    "embedded, carried derivatives (var 0)": {"unmodelled_q": 0.0, "carry": True},
    "float64 lik.: embedded, carried (var 0)": {"likelihood": "float64", "unmodelled_q": 0.0, "carry": True},
    "float32 lik.: carried (var 0.01 r)": {"likelihood": "float32", "unmodelled_q": 0.01, "carry": True},
}
