"""NormalHedge tracking and its generative comparators on sliding-detector score maps.

Chaudhuri, Freund & Hsu, "An Online Learning-based Framework for Tracking"
(UAI 2010) on video: ``nh`` (SMC NormalHedge), ``pf`` (SIR particle filter)
and ``bayes`` (exact grid Bayes) all read the same
:class:`~vidtrack.types.ScoreMap`, from the online NCC template detector
(``detector="ncc"``, default) or OpenCV's cascade face detector
(``detector="face"``, the seed's motivating example).  ``nh-face``,
``pf-face`` and ``bayes-face`` are the same trackers with the face detector
as their default, so ``vidtrack eval`` can compare them on face sequences.
"""

from __future__ import annotations

import numpy as np

from ..filters.score_trackers import GridBayesBoxFilter, NormalHedgeBoxFilter, ParticleBoxFilter
from ..filters.box import MeasuredSizeFilter
from ..measure.detectors import make_detector
from ..tracker import Recipe, Tracker

DETECTOR_OPTION = frozenset({"detector"})


def _builder(make_filter, default_detector: str = "cf"):
    def build(seed=None, detector: str = default_detector) -> Tracker:
        # the box size follows the detector's scale estimate (the cf detector searches scales)
        return Tracker(make_detector(detector), MeasuredSizeFilter(make_filter(np.random.default_rng(seed))))
    return build


RECIPES = {
    # nh and bayes on the correlation-filter map: more actions, a shorter regret memory, wider
    # re-sampling; a wider random walk (chosen on the tune split; see vidtrack.filters.score_trackers)
    "nh": Recipe("SMC NormalHedge on a sliding-detector score map (Chaudhuri, Freund & Hsu 2010)",
                 _builder(lambda rng: NormalHedgeBoxFilter(n_actions=300, alpha=0.6, sigma_star=0.35, rng=rng)),
                 options=DETECTOR_OPTION),
    "pf": Recipe("SIR particle filter on a sliding-detector score map (NormalHedge paper's comparator)",
                 _builder(lambda rng: ParticleBoxFilter(rng=rng)), options=DETECTOR_OPTION),
    "bayes": Recipe("exact grid Bayes filter on a sliding-detector score map (NormalHedge paper's comparator)",
                    _builder(lambda rng: GridBayesBoxFilter(sigma_d=0.15, rng=rng)), options=DETECTOR_OPTION),
    "nh-face": Recipe("nh on OpenCV's Haar face-detector score map (the seed's motivating example)",
                      _builder(lambda rng: NormalHedgeBoxFilter(rng=rng), "face"), options=DETECTOR_OPTION),
    "pf-face": Recipe("pf on OpenCV's Haar face-detector score map",
                      _builder(lambda rng: ParticleBoxFilter(rng=rng), "face"), options=DETECTOR_OPTION),
    "bayes-face": Recipe("bayes on OpenCV's Haar face-detector score map",
                         _builder(lambda rng: GridBayesBoxFilter(rng=rng), "face"), options=DETECTOR_OPTION),
}
