"""NormalHedge tracking and its generative comparators on sliding-detector score maps.

Chaudhuri, Freund & Hsu, "An Online Learning-based Framework for Tracking"
(UAI 2010) on video: ``nh`` (SMC NormalHedge), ``pf`` (SIR particle filter)
and ``bayes`` (exact grid Bayes) all read the same
:class:`~vidtrack.types.ScoreMap`, from the correlation-filter detector
(``detector="cf"``, the default), the online NCC template (``"ncc"``) or
OpenCV's cascade face detector (``"face"``, the paper's motivating example).  ``nh-face``,
``pf-face`` and ``bayes-face`` are the same trackers with the face detector
as their default, so ``vidtrack eval`` can compare them on face sequences.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..config import option
from ..filters.box import MeasuredSizeFilter
from ..filters.score_trackers import GridBayesBoxFilter, NormalHedgeBoxFilter, ParticleBoxFilter
from ..measure.correlation_score_map import CorrelationDetectorConfig
from ..measure.detectors import make_detector
from ..measure.verification import VerifiedMeasurer
from ..tracker import Recipe, Tracker

Detector = Literal["cf", "ncc", "face"]
DETECTOR_DOC = "the score map: cf (correlation filter), ncc (grey template) or face (OpenCV's Haar cascade)"
RESEED_DOC = ("while lost, the tracker restarts at the map's peak when the map's quality reaches this and its "
              "own box scores under half the peak (none: never)")
CF_DOC = "the correlation-filter detector (detector cf): its filter, scale search, learning and re-detection"
#: Reach of the appearance verification map, in box sizes around the prior: the calibrated confidence's
#: ``verify_gap`` sees a better match of the first frame's target up to this far from the box
VERIFY_MARGIN = 2.0


@dataclass(frozen=True)
class NormalHedgeConfig:
    """``nh``: SMC NormalHedge over box centres (:class:`~vidtrack.filters.score_trackers.NormalHedgeBoxFilter`)."""

    detector: Detector = option("cf", DETECTOR_DOC)
    n_actions: int = option(100, "N, the number of actions (box centres) NormalHedge weighs")
    alpha: float = option(0.4, "fraction of the actions re-sampled when their weight vanishes")
    sigma_star: float = option(0.25, "random-walk step of a re-sampled action, in box sizes")
    reseed_above: float | None = option(None, RESEED_DOC)
    confidence: str | None = option("nh", "calibrated confidence: vidtrack/filters/calibration/<name>.json "
                                           "(none: concentration times quality)")
    cf: CorrelationDetectorConfig = option(CorrelationDetectorConfig(), CF_DOC)


@dataclass(frozen=True)
class ParticleConfig:
    """``pf``: SIR particle filter over box centres (:class:`~vidtrack.filters.score_trackers.ParticleBoxFilter`)."""

    detector: Detector = option("cf", DETECTOR_DOC)
    n_particles: int = option(100, "number of particles")
    sigma_d: float = option(0.2, "random-walk step of a particle per frame, in box sizes")
    reseed_above: float | None = option(None, RESEED_DOC)
    confidence: str | None = option("pf", "calibrated confidence: vidtrack/filters/calibration/<name>.json "
                                           "(none: concentration times quality)")
    cf: CorrelationDetectorConfig = option(CorrelationDetectorConfig(), CF_DOC)


@dataclass(frozen=True)
class GridBayesConfig:
    """``bayes``: exact Bayes filter on a grid of box centres (:class:`~vidtrack.filters.score_trackers.GridBayesBoxFilter`)."""

    detector: Detector = option("cf", DETECTOR_DOC)
    sigma_d: float = option(0.1, "random-walk step per frame, in box sizes")
    reseed_above: float | None = option(None, RESEED_DOC)
    confidence: str | None = option("bayes", "calibrated confidence: vidtrack/filters/calibration/<name>.json "
                                           "(none: concentration times quality)")
    cf: CorrelationDetectorConfig = option(CorrelationDetectorConfig(), CF_DOC)


def _calibrated(config) -> str | None:
    """The calibration a configuration names; fitted on the cf detector's maps, so none for the others."""
    return config.confidence if config.detector == "cf" else None


def _tracker(config, box_filter) -> Tracker:
    # the box size follows the detector's scale estimate (the cf detector searches scales); the
    # verification map (first-frame appearance) is a cue of the calibrated confidence only
    options = {"cf": config.cf} if config.detector == "cf" else {}
    measurer = VerifiedMeasurer(make_detector(config.detector, **options), margin=VERIFY_MARGIN)
    return Tracker(measurer, MeasuredSizeFilter(box_filter))


def build_nh(config: NormalHedgeConfig, seed=None) -> Tracker:
    return _tracker(config, NormalHedgeBoxFilter(n_actions=config.n_actions, alpha=config.alpha,
                                                          sigma_star=config.sigma_star,
                                                          confidence=_calibrated(config),
                                                          reseed_above=config.reseed_above,
                                                          rng=np.random.default_rng(seed)))


def build_pf(config: ParticleConfig, seed=None) -> Tracker:
    return _tracker(config, ParticleBoxFilter(n_particles=config.n_particles, sigma_d=config.sigma_d,
                                                       rng=np.random.default_rng(seed),
                                                       reseed_above=config.reseed_above,
                                                       confidence=_calibrated(config)))


def build_bayes(config: GridBayesConfig, seed=None) -> Tracker:
    return _tracker(config, GridBayesBoxFilter(sigma_d=config.sigma_d, rng=np.random.default_rng(seed),
                                                        reseed_above=config.reseed_above,
                                                        confidence=_calibrated(config)))


# On the correlation-filter map: nh keeps more actions and a shorter regret memory, pf and
# bayes read a detector solved over every past sample and bayes walks wider; all three
# restart at a confident re-detection while lost (see vidtrack.filters.score_trackers)
#: The detector solved over every past sample, as mil's filter is (ECO's objective; see CorrelationConfig)
EVERY_SAMPLE_CF = CorrelationDetectorConfig(second_moment=True, support=0.85, solve_interval=3, admm_iterations=4)
NH = NormalHedgeConfig(n_actions=300, alpha=0.6, reseed_above=0.7)
PF = ParticleConfig(reseed_above=0.7, cf=EVERY_SAMPLE_CF)
BAYES = GridBayesConfig(sigma_d=0.2, reseed_above=0.7, cf=EVERY_SAMPLE_CF)

RECIPES = {
    "nh": Recipe("SMC NormalHedge on a sliding-detector score map (Chaudhuri, Freund & Hsu 2010)", build_nh, NH),
    "pf": Recipe("SIR particle filter on a sliding-detector score map (NormalHedge paper's comparator)",
                 build_pf, PF),
    "bayes": Recipe("exact grid Bayes filter on a sliding-detector score map (NormalHedge paper's comparator)",
                    build_bayes, BAYES),
    "nh-face": Recipe("nh on OpenCV's Haar face-detector score map (the motivating example of Chaudhuri, "
                      "Freund & Hsu)", build_nh, NormalHedgeConfig(detector="face")),
    "pf-face": Recipe("pf on OpenCV's Haar face-detector score map", build_pf, ParticleConfig(detector="face")),
    "bayes-face": Recipe("bayes on OpenCV's Haar face-detector score map", build_bayes,
                         GridBayesConfig(detector="face")),
}
