"""Support Vector Kalman on mean-shift measurements (Salti & Di Stefano, section 8).

As in the paper's video experiments (and :mod:`vidtrack.recipes.classic`'s
Kalman-MS), the mean-shift search starts at the filter's prediction.  The
SVK core tracks the box centre with state ``[p_x, v_x, p_y, v_y]``: four
linear SVRs, each regressing one component from the whole previous state,
learn ``F`` and the diagonal ``Q`` online from the last ``window`` filtered
states.  Until the window is full it runs a constant-velocity model tuned
like ``kalman-cv``.  Measurement noise and the ``Q`` floor scale with the box
size like the classic trackers'.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ..config import option
from ..filters.svk import SupportVectorKalman, SVKCentreFilter
from ..tracker import Recipe, Tracker
from ..types import Box
from .classic import MeanShiftConfig, kalman_core, meanshift


@dataclass(frozen=True)
class SVRConfig:
    """The online SVR that learns ``F`` and ``Q`` (:class:`~vidtrack.filters.svk.SupportVectorKalman`).

    The paper gives no ``C`` for its video experiments; its linear-motion value
    ``2**-10`` is the default (a larger ``C`` learns an ``F`` that can be
    unstable while the target is lost and the filter coasts).
    """

    C: float = option(2.0 ** -10, "SVR regularisation weight (the paper: 2^-10 on linear motion, 2 on non-linear)")
    epsilon: float = option(0.1, "SVR insensitivity, in normalised units (outputs scaled to [-1, 1])")
    window: int = option(10, "W, the number of state pairs in the sliding training window")
    n_folds: int = option(5, "folds of the cross-validation that estimates Q")
    q_floor: float = option(0.1, "Q_ii never goes below this fraction of the matching R entry")


@dataclass(frozen=True)
class SVKConfig:
    """``svk``: mean-shift measurements, the SVR-learned Kalman filter."""

    meanshift: MeanShiftConfig = option(MeanShiftConfig(), "the mean-shift measurer")
    svr: SVRConfig = option(SVRConfig(), "the online SVR learning the transition model")


def svk_core(box: Box, svr: SVRConfig = SVRConfig()) -> SupportVectorKalman:
    """A 2-axis SVK core for ``box``, bootstrapped from ``kalman-cv``'s model (:func:`kalman_core`).

    Its own ``R`` is a fallback: on video every update passes the mean-shift
    measurement's covariance (:class:`~vidtrack.filters.box.CentreFilter`).
    """
    cv = kalman_core("cv", box)
    return SupportVectorKalman(cv.H, cv.R, cv.F, cv.Q, **asdict(svr))


def build_svk(config: SVKConfig, seed=None) -> Tracker:
    return Tracker(meanshift(config.meanshift), SVKCentreFilter(lambda box: svk_core(box, config.svr), order=2))


RECIPES = {
    "svk": Recipe("Support Vector Kalman (online SVR-learned F, Q) on mean-shift measurements "
                  "(Salti & Di Stefano)", build_svk, SVKConfig()),
}
