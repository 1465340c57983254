"""Unassociated detections from a sliding detector's score map.

A frame's detections are the local maxima of a detector's score map (the
correlation filter of :mod:`vidtrack.measure.correlation` by default, or the
NCC template of :mod:`vidtrack.measure.score_map`) after non-maximum suppression: every peak
above ``min_score``, at most ``max_detections``, no two closer than
``nms_fraction`` of the box size.  Clutter (peaks on background that look a
bit like the target) is kept on purpose and nothing associates a detection
with the target: the channel-based tracker (:class:`~vidtrack.filters.cbt.CBTFilter`)
sorts that out, as in "Learning Object Tracking in Image Sequences"
(Felsberg & Larsson), whose RC-car experiment tracks from such detections.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import maximum_filter

from ..types import Box, Detections, Estimate, Frame, ScoreMap
from .correlation_score_map import CorrelationDetectorConfig
from .detectors import make_detector


def score_map_peaks(scores: np.ndarray, *, radius: int, min_score: float = 0.2,
                    max_peaks: int = 10) -> np.ndarray:
    """Local maxima of a score map after non-maximum suppression.

    Parameters
    ----------
    scores : (H, W) float
    radius
        A peak must be the maximum of its ``(2 radius + 1)^2`` neighbourhood.
    min_score
        Peaks below this score are dropped.
    max_peaks
        Keep the strongest ``max_peaks``.

    Returns
    -------
    (N, 3) float array ``[row, col, score]``, strongest first.
    """
    scores = np.asarray(scores, dtype=float)
    if scores.size == 0:
        return np.zeros((0, 3))
    size = 2 * max(int(radius), 0) + 1
    peaks = (scores == maximum_filter(scores, size=size, mode="constant", cval=-np.inf)) & (scores >= min_score)
    rows, cols = np.nonzero(peaks)
    values = scores[rows, cols]
    order = np.argsort(-values, kind="stable")[:max_peaks]
    return np.column_stack([rows[order], cols[order], values[order]]).astype(float)


def detections_from_score_map(score_map: ScoreMap, *, nms_fraction: float = 0.3, min_score: float = 0.2,
                              max_detections: int = 10) -> Detections:
    """The :class:`~vidtrack.types.Detections` of a :class:`~vidtrack.types.ScoreMap` (centres, scores, boxes).

    ``stages`` carries ``score_map`` and ``detections`` (``(N, 3)`` ``[x, y, score]``).
    """
    w, h = score_map.box_size
    radius = int(round(nms_fraction * min(w, h) / max(score_map.step, 1e-9)))
    peaks = score_map_peaks(score_map.scores, radius=radius, min_score=min_score, max_peaks=max_detections)
    boxes = np.array([score_map.box_at(r, c).as_array() for r, c, _ in peaks]).reshape(-1, 4)
    points = boxes[:, :2] + boxes[:, 2:] / 2.0
    scores = peaks[:, 2].copy()
    stages = dict(score_map.stages)
    stages.setdefault("score_map", score_map.scores)
    stages["detections"] = np.column_stack([points, scores]) if len(points) else np.zeros((0, 3))
    quality = float(np.clip(scores.max(), 0.0, 1.0)) if len(scores) else 0.0
    return Detections(points=points, scores=scores, boxes=boxes, quality=quality,
                      search_region=score_map.search_region, stages=stages)


@dataclass
class DetectionMeasurer:
    """Detections per frame from a sliding detector around the prior.

    Parameters
    ----------
    detector
        ``"cf"``: the correlation-filter detector (its own scale search and
        re-detection while lost; detection scores are the map's scores times
        its PSR quality, so a frame without a clear target has weak
        detections); ``"ncc"``: the grey NCC template.
    margin
        NCC search window = prior box grown by this many box sizes on each side.
    lost_margin
        NCC search margin while the prior's status is ``lost`` (a wider search to re-acquire).
    nms_fraction
        Non-maximum suppression radius, as a fraction of the smaller box side.
    min_score
        Lowest score reported as a detection.
    max_detections
        At most this many detections per frame.
    cf
        The ``cf`` detector's configuration
        (:class:`~vidtrack.measure.correlation_score_map.CorrelationDetectorConfig`).
    """

    detector: str = "cf"
    margin: float = 1.0
    lost_margin: float = 2.0
    nms_fraction: float = 0.3
    min_score: float = 0.4
    max_detections: int = 10
    cf: CorrelationDetectorConfig = field(default_factory=CorrelationDetectorConfig)

    def initialize(self, frame: Frame, box: Box) -> None:
        options = {"margin": self.margin} if self.detector == "ncc" else {"cf": self.cf}
        self.detector_ = make_detector(self.detector, **options)
        self.detector_.initialize(frame, box)

    def measure(self, frame: Frame, prior: Estimate) -> Detections | None:
        if self.detector == "ncc":
            self.detector_.margin = self.lost_margin if prior.status == "lost" else self.margin
        score_map = self.detector_.measure(frame, prior)
        if score_map is None:
            return None
        if self.detector == "cf":
            score_map = replace(score_map, scores=score_map.scores * np.float32(score_map.quality))
        return detections_from_score_map(score_map, nms_fraction=self.nms_fraction, min_score=self.min_score,
                                         max_detections=self.max_detections)

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        self.detector_.learn(frame, posterior)
