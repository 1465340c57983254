"""Multiple Instance Filtering (Wnuk & Soatto): ``mil`` and the paper's own tracker, ``mil-paper``.

Both are :class:`~vidtrack.measure.mil_fusion.MILMeasurer` (SLIC superpixels,
Pegasos SVM, graph-cut inliers, and optionally a correlation filter fused
with them) in a :class:`~vidtrack.filters.mil.MILKalmanFilter`, configured by
one :class:`MILConfig`: groups ``superpixels``, ``svm``, ``graphcut``,
``correlation``, ``fusion`` and ``kalman`` (``--set fusion.redetect=false``).

``mil`` is the default configuration: the paper's tracker with the
correlation filter's centre, scale, re-detection and presence, the bag grown
while lost, and a Kalman filter with damped velocities.

``mil-paper`` is the tracker of "Multiple Instance Filtering" with every
extension off, decided field by field:

* ``fusion``: no correlation filter (``refine`` off, ``size_from="inliers"``:
  the measured size is the inlier extent, the paper's ``h_2``), hence no
  re-detection (``redetect`` off) and no presence test (``present`` none):
  a frame without inliers is predicted only and reported lost;
* ``graphcut.lost_bag`` off: the positive bag is the predicted box whether
  or not the target was measured (eq. 8's covariance still sets the search
  region, ``superpixels.lam = 3``);
* ``kalman``: the paper's constant-velocity ``F`` (``size_damping = 1``),
  also while coasting (``coast_damping = 1``: the paper's open loop); the
  paper gives no noise covariances, so they are ``mil``'s;
* what the paper fixes is the same in both: ``lam = 3``, ``gamma_max = 25``,
  an update every 6 frames, positives at 70 % of their area in the box,
  Pegasos on chi-squared feature maps, the graph cut inside the positive
  bag, the box at the peak of the smoothed inlier map (fig. 3);
* where the paper leaves a choice open, ``mil-paper`` keeps ``mil``'s
  assumptions (:mod:`vidtrack.measure.mil` lists them): the search region's
  padding and resolution, the superpixel size, the descriptor, Pegasos'
  batches and step cap, the first frame kept as an anchor, learning only
  from confident frames, the spatial prior in the cut, the calibration of
  ``h`` on the first frame and the coverage a size measurement needs, and
  the filter's noise, gate and size limits.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..config import option
from ..filters.mil import KalmanConfig, MILKalmanFilter
from ..measure.mil import GraphCutConfig
from ..measure.mil_fusion import FusionConfig, MILMeasurer, MILMeasurerConfig
from ..measure.verification import VerifiedMeasurer
from ..tracker import Recipe, Tracker


@dataclass(frozen=True)
class MILConfig(MILMeasurerConfig):
    """``mil``: the measurer's groups (superpixels, svm, graphcut, correlation, fusion) and the Kalman filter."""

    kalman: KalmanConfig = option(KalmanConfig(), "the Kalman filter on the box")


def build_mil(config: MILConfig, seed=None, *, threads: bool = True) -> Tracker:
    """The MIL tracker of ``config``; ``threads`` runs the correlation filter on a second thread (same boxes).

    With a calibrated confidence the measurer is wrapped in the first frame's appearance verification
    (:class:`~vidtrack.measure.verification.VerifiedMeasurer`, its map at the predicted box size only), whose
    cues the calibration reads; the measurements are the same, and so are the boxes until the calibrated
    status reports a frame lost, which is then searched as an unmeasured one (``fusion.search_when_lost``).
    """
    measurer = MILMeasurer(config, rng=seed, threads=threads)
    if config.kalman.confidence is not None:
        measurer = VerifiedMeasurer(measurer, size_factors=())
    return Tracker(measurer, MILKalmanFilter(config.kalman))


MIL = MILConfig()

MIL_PAPER = MILConfig(
    graphcut=GraphCutConfig(lost_bag=False),
    fusion=FusionConfig(refine=False, size_from="inliers", redetect=False, present=None, search_when_lost=False),
    kalman=KalmanConfig(coast_damping=1.0, size_damping=1.0, confidence=None),
)

RECIPES = {
    "mil": Recipe("Multiple Instance Filtering: SLIC superpixels + Pegasos SVM + graph-cut inliers in a Kalman "
                  "filter (Wnuk & Soatto), fused with a correlation filter", build_mil, MIL),
    "mil-paper": Recipe("Multiple Instance Filtering as in Wnuk & Soatto's paper: mil without the correlation "
                        "filter and the other extensions", build_mil, MIL_PAPER),
}
