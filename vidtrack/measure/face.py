"""Face-detector score maps: OpenCV's cascade face detector as a sliding detector.

The motivating example of Chaudhuri, Freund & Hsu, "An Online Learning-based
Framework for Tracking" (UAI 2010), Section 5: a face detector (Viola & Jones
2001) scores regions of the frame; it fires on several boxes around a face
and sometimes elsewhere.  :class:`FaceScoreMapMeasurer` runs the cascade in a
search window around the prior and paints a :class:`~vidtrack.types.ScoreMap`
over box positions: a position's score is the best ``IoU(box, detection) *
strength`` over the detections (0 where nothing fired), where ``strength``
grows with the number of merged raw detections (``detectMultiScale2``).

The cascade file comes from the environment variable
``VIDTRACK_FACE_CASCADE`` if set, else from ``cv2.data.haarcascades``: the
OpenCV 4 wheels ship ``haarcascade_frontalface_default.xml`` there, which is
why vidtrack requires ``opencv-contrib-python-headless<5`` (the 5.0 wheels
ship an empty ``cv2/data``, opencv-python issue #1244).  With no loadable
cascade the detector raises :class:`~vidtrack.errors.UsageError`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ..errors import UsageError
from ..types import Box, Estimate, Frame, ScoreMap
from .score_map import search_window

CASCADE_NAMES = ("haarcascade_frontalface_default.xml", "haarcascade_frontalface_alt2.xml")

#: ``detect(gray_uint8) -> (boxes (K, 4) [x, y, w, h], strengths (K,))``.
DetectFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def find_face_cascade() -> Path:
    """Path of a loadable face cascade; :class:`UsageError` when none is available."""
    candidates = []
    env = os.environ.get("VIDTRACK_FACE_CASCADE")
    if env:
        candidates.append(Path(env))
    data = getattr(getattr(cv2, "data", None), "haarcascades", None)
    if data:
        candidates += [Path(data) / name for name in CASCADE_NAMES]
    for path in candidates:
        if path.is_file() and not cv2.CascadeClassifier(str(path)).empty():
            return path
    raise UsageError("--detector face needs a Haar face cascade: this OpenCV build ships none in "
                     "cv2.data.haarcascades (install opencv-contrib-python-headless<5, or set "
                     "VIDTRACK_FACE_CASCADE to a haarcascade_frontalface_default.xml)")


def cascade_detector(path: Path, *, scale_factor: float = 1.1, min_neighbors: int = 2) -> DetectFn:
    """A :data:`DetectFn` running the cascade at ``path`` (strength = 1 - 1/(1 + neighbours))."""
    classifier = cv2.CascadeClassifier(str(path))

    def detect(gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes, counts = classifier.detectMultiScale2(gray, scaleFactor=scale_factor, minNeighbors=min_neighbors)
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        counts = np.asarray(counts, dtype=float).reshape(-1)
        return boxes, 1.0 - 1.0 / (1.0 + counts)

    return detect


def iou_map(x0: np.ndarray, y0: np.ndarray, size: tuple[float, float], box: np.ndarray) -> np.ndarray:
    """IoU of boxes of ``size`` with top-left corners on the grid ``x0 (W,)`` x ``y0 (H,)`` against ``box``."""
    w, h = size
    bx, by, bw, bh = box
    ix = np.clip(np.minimum(x0 + w, bx + bw) - np.maximum(x0, bx), 0, None)
    iy = np.clip(np.minimum(y0 + h, by + bh) - np.maximum(y0, by), 0, None)
    inter = iy[:, None] * ix[None, :]
    return inter / (w * h + bw * bh - inter)


def detections_score_map(boxes: np.ndarray, strengths: np.ndarray, region: Box, box_size: tuple[float, float],
                         step: float) -> tuple[np.ndarray, tuple[float, float]]:
    """Scores ``(H', W')`` over box positions in ``region``: max over detections of IoU times strength."""
    w, h = box_size
    x0 = np.arange(region.x, max(region.x + region.w - w, region.x) + 1e-9, step)
    y0 = np.arange(region.y, max(region.y + region.h - h, region.y) + 1e-9, step)
    scores = np.zeros((len(y0), len(x0)))
    for box, strength in zip(boxes, strengths):
        scores = np.maximum(scores, strength * iou_map(x0, y0, box_size, box))
    return scores, (float(region.x), float(region.y))


@dataclass
class FaceScoreMapMeasurer:
    """Cascade face detector in a window around the prior, as a score map over box positions.

    Parameters
    ----------
    margin
        Search window = prior box grown by this many box sizes each side.
    step
        Spacing of the map's box positions, pixels.
    detect
        Detector override (tests); default: the cascade :func:`find_face_cascade` finds.
    """

    margin: float = 1.0
    step: float = 2.0
    detect: DetectFn | None = None

    def initialize(self, frame: Frame, box: Box) -> None:
        self.detect_ = self.detect if self.detect is not None else cascade_detector(find_face_cascade())
        self.box_size_ = (float(box.w), float(box.h))

    def measure(self, frame: Frame, prior: Estimate) -> ScoreMap | None:
        cx, cy = prior.box.center
        region = search_window(Box.from_center(cx, cy, *self.box_size_), self.margin, frame.width, frame.height)
        if region.w < self.box_size_[0] or region.h < self.box_size_[1]:
            return None
        x0, y0 = int(region.x), int(region.y)
        crop = frame.image[y0:int(np.ceil(region.y + region.h)), x0:int(np.ceil(region.x + region.w))]
        if crop.ndim == 3:   # only the search window is converted to grey
            crop = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
        boxes, strengths = self.detect_(np.ascontiguousarray(crop))
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4) + np.array([x0, y0, 0, 0])
        scores, origin = detections_score_map(boxes, np.asarray(strengths, float), region, self.box_size_, self.step)
        peak = float(scores.max()) if scores.size else 0.0
        return ScoreMap(scores=scores, origin=origin, step=self.step, box_size=self.box_size_,
                        quality=peak, search_region=region,
                        stages={"score_map": scores, "detections": np.column_stack(
                            [boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3] / 2, strengths])
                            if len(boxes) else np.zeros((0, 3))})

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        """The cascade is fixed: nothing to learn."""
