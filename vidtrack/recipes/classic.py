"""The classic baselines: mean-shift alone, Kalman DR/CV/CA and IMM on mean-shift measurements.

Following Comaniciu et al. (Kalman-MS) and Salti & Di Stefano's video
experiments, the mean-shift search starts at the filter's prediction.
Process noise scales with the box size ``s = sqrt(w h)``: the highest
derivative a model carries takes a random step of standard deviation
``q_scale * s`` per frame.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..config import option
from ..filters.box import CentreFilter, PassThroughFilter
from ..filters.imm import IMMEstimator, sticky_transition_matrix
from ..filters.kalman import MOTION_ORDERS, KalmanFilter, motion_model
from ..measure.meanshift import MeanShiftMeasurer
from ..tracker import Recipe, Tracker
from ..types import Box

#: Bhattacharyya coefficient below which a mean-shift measurement is not used and the target is lost.
LOST_BELOW = 0.4

#: Per-frame random step of the highest derivative, as a fraction of the box size.
Q_SCALE = {"dr": 0.08, "cv": 0.02, "ca": 0.006}


def kalman_core(model: str, box: Box, order: int | None = None) -> KalmanFilter:
    """A 2-axis Kalman filter with ``model`` dynamics and noise scaled to ``box``."""
    q = (Q_SCALE[model] * box.scale) ** 2
    F, Q, H = motion_model(model, q=q, n_axes=2, order=order)
    return KalmanFilter(F, Q, H, np.eye(2) * (0.1 * box.scale) ** 2)


def imm_core(box: Box, models=("dr", "cv", "ca"), stay: float = 0.95) -> IMMEstimator:
    """IMM over ``models`` embedded in a common constant-acceleration state."""
    order = max(MOTION_ORDERS[m] for m in models)
    filters = [kalman_core(m, box, order=order) for m in models]
    return IMMEstimator(filters, sticky_transition_matrix(len(filters), stay))


@dataclass(frozen=True)
class MeanShiftConfig:
    """Options of the mean-shift measurer (:class:`~vidtrack.measure.meanshift.MeanShiftMeasurer`)."""

    bins: int = option(16, "histogram bins per colour channel (grey images use twice as many)")
    background_weighting: bool = option(True, "background-weighted target histogram (Comaniciu et al., sec. 6.1)")
    scale_step: float = option(0.0, "relative size change tried each frame (0: the size stays the init size)")
    scale_gamma: float = option(0.1, "blend of the best size with the previous one")
    position_sigma: float = option(0.04, "measurement standard deviation at rho = 1, fraction of the box size")


def meanshift(config: MeanShiftConfig) -> MeanShiftMeasurer:
    """The mean-shift measurer configured by ``config``."""
    return MeanShiftMeasurer(**asdict(config))


def build_ms(config: MeanShiftConfig, seed=None) -> Tracker:
    return Tracker(meanshift(config), PassThroughFilter(lost_below=LOST_BELOW))


def build_kalman(model: str):
    def build(config: MeanShiftConfig, seed=None) -> Tracker:
        order = MOTION_ORDERS[model]
        return Tracker(meanshift(config),
                       CentreFilter(lambda box: kalman_core(model, box), order=order, lost_below=LOST_BELOW))
    return build


def build_imm(config: MeanShiftConfig, seed=None) -> Tracker:
    return Tracker(meanshift(config), CentreFilter(imm_core, order=3, lost_below=LOST_BELOW))


RECIPES = {
    "ms": Recipe("mean-shift alone on a colour histogram (Comaniciu et al. 2003)", build_ms, MeanShiftConfig()),
    "kalman-dr": Recipe("Kalman filter, drift model, on mean-shift measurements", build_kalman("dr"),
                        MeanShiftConfig()),
    "kalman-cv": Recipe("Kalman filter, constant velocity, on mean-shift measurements", build_kalman("cv"),
                        MeanShiftConfig()),
    "kalman-ca": Recipe("Kalman filter, constant acceleration, on mean-shift measurements", build_kalman("ca"),
                        MeanShiftConfig()),
    "imm": Recipe("Interacting Multiple Model (DR+CV+CA) on mean-shift measurements", build_imm, MeanShiftConfig()),
}
