"""Channel-Based Tracking on video: ``--filter cbt``.

Detections per frame are the local maxima of the correlation-filter
detector's score map (``detector="ncc"``: the NCC template's), clutter
included and never associated with the target
(:class:`~vidtrack.measure.detections.DetectionMeasurer`);
:class:`~vidtrack.filters.cbt.CBTFilter` tracks the box centre from them on a
cos² channel grid that follows the target (Felsberg & Larsson, "Learning Object
Tracking in Image Sequences").  Its motion model is learned online from its
own estimates, or read from ``model`` (``--model FILE``: a ``.npz`` written
by ``vidtrack learn cbt``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Literal

from ..config import option
from ..filters.box import MeasuredSizeFilter
from ..filters.cbt import CBTFilter
from ..filters.cbt_model import CBTModel
from ..measure.correlation_score_map import CorrelationDetectorConfig
from ..measure.detections import DetectionMeasurer
from ..measure.verification import VerifiedMeasurer
from ..tracker import Recipe, Tracker

#: Markov order of the motion model when neither the configuration nor a model file sets it.
DEFAULT_ORDER = 2


@dataclass(frozen=True)
class GridConfig:
    """The cos² position channels (:class:`~vidtrack.filters.cbt.CBTFilter`): a window that follows the target."""

    spacing_boxes: float = option(0.2, "spacing of the position channels, box sizes")
    min_spacing: float = option(2.0, "smallest spacing of the position channels, pixels")
    window_boxes: float = option(10.0, "side of the position grid that follows the target, box sizes")
    min_window: float = option(64.0, "smallest side of the position grid, pixels")


@dataclass(frozen=True)
class DetectionsConfig:
    """How a frame's detections are found (:class:`~vidtrack.measure.detections.DetectionMeasurer`)."""

    margin: float = option(1.0, "ncc: search window = the prior box grown by this many box sizes on each side")
    lost_margin: float = option(2.0, "ncc: the search margin while the target is lost (a wider search)")
    nms_fraction: float = option(0.3, "non-maximum suppression radius, fraction of the smaller box side")
    min_score: float = option(0.4, "lowest detector score reported as a detection")
    max_detections: int = option(10, "at most this many detections per frame")
    cf: CorrelationDetectorConfig = option(CorrelationDetectorConfig(), "the correlation-filter detector "
                                           "(detector cf): its filter, scale search, learning and re-detection")


@dataclass(frozen=True)
class CBTConfig:
    """``cbt``: unassociated detections, a channel-based filter with a learned motion model."""

    model: str | None = option(None, "motion model file written by 'vidtrack learn cbt' (none: learned online)")
    detector: Literal["cf", "ncc"] = option("cf", "the detector: cf (correlation filter) or ncc (grey template)")
    order: int | None = option(None, f"Markov order of the motion model (none: the model file's, else "
                                      f"{DEFAULT_ORDER})")
    relearn_every: int = option(10, "tracked frames between re-estimates of the online motion model")
    prior_weight: float = option(20.0, "pseudo-counts of the random-walk prior in the online motion model")
    learn_online: bool = option(True, "learn the motion model while tracking (without a model file)")
    prior_sigma: float = option(0.2, "random-walk prior: displacement standard deviation, box sizes per frame")
    d_channels: int = option(15, "channels of the displacement model")
    d_range: float = option(1.0, "largest displacement per frame the motion model represents, box sizes")
    clutter: float = option(0.02, "likelihood floor (clutter and missed detections)")
    score_temperature: float = option(0.05, "temperature of the detection weights exp((score - top) / T)")
    relative_scores: bool = option(True, "weigh detections relative to the frame's best score (false: to 1)")
    product: Literal["plain", "sqrt"] = option("plain", "product of channel vectors in the update")
    lost_below: float = option(0.2, "cbt's own confidence below which a frame is not measured (the box is the "
                                           "prediction, and the frame is lost)")
    mass_full: float = option(0.5, "posterior mass of the decoded mode that counts as full confidence")
    mode_threshold: float = option(0.05, "mass a posterior mode must hold to count in the 'modes' scalar")
    coast_when_lost: bool = option(True, "forget the learned velocity on a frame that is not measured")
    confidence: str | None = option("cbt", "calibrated confidence: vidtrack/filters/calibration/<name>.json, "
                                           "fitted on the cf detector (none, or detector ncc: the mode mass "
                                           "times the best nearby score)")
    grid: GridConfig = option(GridConfig(), "the position channels: their spacing and the window they cover")
    detections: DetectionsConfig = option(DetectionsConfig(), "how a frame's detections are found")


def cbt_filter(config: CBTConfig, model: CBTModel | None = None) -> CBTFilter:
    """The :class:`CBTFilter` configured by ``config``, with ``model`` (already read) if given.

    Without ``config.order`` the order is the model's; an order that
    contradicts the model's is a UsageError when the filter starts.
    """
    order = config.order if config.order is not None else (model.order if model is not None else DEFAULT_ORDER)
    return CBTFilter(order=order, **asdict(config.grid), d_channels=config.d_channels, d_range=config.d_range,
                     prior_sigma=config.prior_sigma,
                     prior_weight=config.prior_weight, relearn_every=config.relearn_every, clutter=config.clutter,
                     score_temperature=config.score_temperature, product=config.product,
                     learn_online=config.learn_online, lost_below=config.lost_below, mass_full=config.mass_full,
                     model=model, mode_threshold=config.mode_threshold, coast_when_lost=config.coast_when_lost,
                     relative_scores=config.relative_scores,
                     confidence=config.confidence if config.detector == "cf" else None)


def build_cbt(config: CBTConfig, seed=None) -> Tracker:
    """CBT tracker; reads ``config.model`` (a UsageError names a missing or malformed file)."""
    model = None if config.model is None else CBTModel.load(config.model)
    detections = {f.name: getattr(config.detections, f.name) for f in fields(config.detections)}  # cf stays a config
    measurer = VerifiedMeasurer(DetectionMeasurer(detector=config.detector, **detections))
    return Tracker(measurer, MeasuredSizeFilter(cbt_filter(config, model)))


RECIPES = {
    "cbt": Recipe("Channel-Based Tracking (cos² channels, learned motion) on correlation-filter detections",
                  build_cbt, CBTConfig()),
}
