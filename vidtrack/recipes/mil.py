"""Multiple Instance Filtering (Wnuk & Soatto): SLIC superpixels, Pegasos SVM and graph-cut inliers in a Kalman filter.

``build(seed=..., **options)``: options naming a :class:`~vidtrack.measure.mil.MILMeasurer`
parameter go to the measurer, those naming a
:class:`~vidtrack.filters.mil.MILKalmanFilter` parameter to the filter.
"""

from __future__ import annotations

from ..filters.mil import MILKalmanFilter
from ..measure.mil import MILMeasurer
from ..tracker import Recipe, Tracker


def build_mil(config=None, seed=None) -> Tracker:
    return Tracker(MILMeasurer(rng=seed), MILKalmanFilter())


RECIPES = {
    "mil": Recipe("Multiple Instance Filtering: SLIC superpixels + Pegasos SVM + graph-cut inliers "
                  "in a Kalman filter (Wnuk & Soatto)", build_mil),
}
