"""The correlation-filter detector as a score-map measurer (``--detector cf``, the default).

The filter of :mod:`vidtrack.measure.correlation` searches a window around
the prior each frame; its response over that window is a
:class:`~vidtrack.types.ScoreMap` over box positions, which the NormalHedge,
particle, grid-Bayes and channel-based trackers read.  The measurer keeps
the box size (the scale filter's estimate, within limits of the initial
size), re-detects over a wider region while the prior is lost, and lets the
filter learn only from confident frames.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config import option, redefault
from ..types import Box, Estimate, Frame, ScoreMap
from .correlation import CorrelationConfig, CorrelationFilter, CorrelationResult
from .scale_filter import ScaleFilter


@dataclass(frozen=True)
class CorrelationDetectorConfig(CorrelationConfig):
    """The score-map detector: the :class:`~vidtrack.measure.correlation.CorrelationConfig` fields and its own.

    It differs from ``mil``'s filter in how it learns: from a re-cut window
    (``reuse_sample`` off), from the average sample over the box's full extent
    at every update (``second_moment`` off, ``support`` 1, ``solve_interval``
    1, ``admm_iterations`` 2), and with each scale of its scale filter
    resampled to DSST's 512 pixels (``scale_area``).
    """

    reuse_sample: bool = redefault(CorrelationConfig, "reuse_sample", False)
    scale_area: float = redefault(CorrelationConfig, "scale_area", ScaleFilter.model_area)
    second_moment: bool = redefault(CorrelationConfig, "second_moment", False)
    support: float = redefault(CorrelationConfig, "support", 1.0)
    solve_interval: int = redefault(CorrelationConfig, "solve_interval", 1)
    admm_iterations: int = redefault(CorrelationConfig, "admm_iterations", 2)
    learn_above: float = option(0.2, "minimum quality of the frame's detection for the filter to learn")
    lost_margin: float = option(1.5, "while lost, the re-detection region reaches this many box sizes "
                                     "on each side of the prior")
    size_limits: tuple[float, float] = option((0.2, 5.0), "the box size stays within these multiples "
                                                          "of the initial size")


def result_score_map(result: CorrelationResult) -> ScoreMap:
    """The response as a :class:`~vidtrack.types.ScoreMap` over box positions (scores divided by the peak)."""
    h, w = result.response.shape
    bw, bh = result.size
    origin = (float(result.window_centre[0] - (w // 2) * result.step - bw / 2.0),
              float(result.window_centre[1] - (h // 2) * result.step - bh / 2.0))
    scores = (result.response / max(result.peak, 1e-9)).astype(np.float32)
    region = Box(origin[0], origin[1], (w - 1) * result.step + bw, (h - 1) * result.step + bh)
    return ScoreMap(scores=scores, origin=origin, step=result.step, box_size=(float(bw), float(bh)),
                    quality=result.quality, search_region=region,
                    stages={"score_map": scores, "psr": float(result.psr)})


class CorrelationScoreMapMeasurer:
    """The correlation-filter detector as a :class:`~vidtrack.types.ScoreMap` measurer.

    Each frame the filter searches the window around the prior's centre at
    the detector's current box size, and the scale filter estimates the
    size change at the peak; the map is the response (divided by its peak,
    so the best box scores 1) over the box positions of that window, its
    ``box_size`` the new size and its ``quality`` the PSR quality.  While
    the prior is ``lost`` the filter is first slid over a region of
    ``lost_margin`` box sizes on each side of it
    (:meth:`~vidtrack.measure.correlation.CorrelationFilter.search`, target
    cells only) and the window is searched around that region's best peak.
    The filter learns only from frames whose posterior is ``tracking`` and
    whose quality reached ``learn_above``.

    Parameters
    ----------
    config
        The detector's :class:`CorrelationDetectorConfig` (its filter fields
        configure the :class:`~vidtrack.measure.correlation.CorrelationFilter`).
    """

    def __init__(self, config: CorrelationDetectorConfig = CorrelationDetectorConfig()) -> None:
        self.config = config

    def initialize(self, frame: Frame, box: Box) -> None:
        self.filter_ = CorrelationFilter(self.config)
        self.filter_.initialize(frame.image, box)
        self.init_size_ = box.size.copy()
        self.last_quality_ = 1.0
        self.size_ = box.size.copy()

    def _clamp_size(self, size: np.ndarray) -> np.ndarray:
        lo, hi = self.config.size_limits
        return np.clip(size, lo * self.init_size_, hi * self.init_size_)

    def measure(self, frame: Frame, prior: Estimate) -> ScoreMap | None:
        centre = prior.box.center
        size = self._clamp_size(self.size_)
        margin = self.config.lost_margin
        if prior.status == "lost" and margin > 0:   # re-detection over a wider region (target only)
            centre = self.filter_.search(frame.image, centre, size * (1.0 + 2.0 * margin), size).centre
        result = self.filter_.detect(frame.image, centre, size)
        result = replace(result, size=self._clamp_size(result.size))
        self.last_quality_ = result.quality
        self.last_size_ = result.size
        return result_score_map(result)

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        if posterior.status != "tracking" or self.last_quality_ < self.config.learn_above:
            return
        self.size_ = self._clamp_size(self.last_size_)
        self.filter_.update(frame.image, Box.from_center(*posterior.box.center, *self.size_))
