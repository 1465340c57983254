"""Multiple Instance Filtering (Wnuk & Soatto): SLIC superpixels, Pegasos SVM and graph-cut inliers in a Kalman filter.

``build(seed=..., **options)``: options naming a :class:`~vidtrack.measure.mil.MILMeasurer`
parameter go to the measurer, those naming a
:class:`~vidtrack.filters.mil.MILKalmanFilter` parameter to the filter.
"""

from __future__ import annotations

from ..filters.mil import MILKalmanFilter
from ..measure.mil import MILMeasurer
from ..tracker import Recipe, Tracker, constructor_options


def build_mil(seed=None, **options) -> Tracker:
    measurer_keys, filter_keys = constructor_options(MILMeasurer), constructor_options(MILKalmanFilter)
    measurer = MILMeasurer(rng=seed, **{k: v for k, v in options.items() if k in measurer_keys})
    filt = MILKalmanFilter(**{k: v for k, v in options.items() if k in filter_keys})
    return Tracker(measurer, filt)


RECIPES = {
    "mil": Recipe("Multiple Instance Filtering: SLIC superpixels + Pegasos SVM + graph-cut inliers "
                  "in a Kalman filter (Wnuk & Soatto)", build_mil,
                  options=constructor_options(MILMeasurer, MILKalmanFilter)),
}
