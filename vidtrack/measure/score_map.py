"""Sliding-detector score maps: dense detector scores over box positions.

The default detector is normalised cross-correlation (NCC) of a grey-level
template against every box position in a search window around the prior
(``cv2.matchTemplate`` with ``TM_CCOEFF_NORMED``, so scores lie in
``[-1, 1]``).  The template is learned from the init box and updated online
by a slow running average while the tracker is confident, so the detector
follows gradual appearance change without absorbing occluders.

The NormalHedge, particle, grid-Bayes and channel-based trackers all read
the :class:`~vidtrack.types.ScoreMap` this produces.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..types import Box, Estimate, Frame, ScoreMap
from .image import to_gray


def search_window(prior: Box, margin: float, width: int, height: int) -> Box:
    """The region searched for boxes of ``prior``'s size: the prior grown by ``margin`` box sizes each side, clipped."""
    grown = Box(prior.x - margin * prior.w, prior.y - margin * prior.h,
                prior.w * (1 + 2 * margin), prior.h * (1 + 2 * margin))
    return grown.clipped(width, height)


def ncc_score_map(gray: np.ndarray, template: np.ndarray, region: Box) -> tuple[np.ndarray, tuple[float, float]]:
    """NCC of ``template`` at every position inside ``region`` of ``gray``.

    Parameters
    ----------
    gray : (H, W) float32
    template : (h, w) float32
    region : Box
        Clipped search region; must be at least the template's size.

    Returns
    -------
    scores : (H', W') float32 in [-1, 1]
        ``scores[i, j]`` for the box with top-left ``origin + (j, i)``.
    origin : (x0, y0)
    """
    x0, y0, x1, y1 = window_pixels(region, template.shape[1], template.shape[0], gray.shape[1], gray.shape[0])
    return _ncc(gray[y0:y1, x0:x1], template), (float(x0), float(y0))


def window_pixels(region: Box, tw: int, th: int, width: int, height: int) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` of ``region`` in a ``width x height`` image, at least the template's ``tw x th``."""
    x0, y0 = int(np.floor(region.x)), int(np.floor(region.y))
    x1, y1 = int(np.ceil(region.x + region.w)), int(np.ceil(region.y + region.h))
    x1, y1 = max(x1, x0 + tw), max(y1, y0 + th)
    x0, y0 = max(0, min(x0, width - tw)), max(0, min(y0, height - th))
    return x0, y0, x1, y1


def _ncc(window: np.ndarray, template: np.ndarray) -> np.ndarray:
    scores = cv2.matchTemplate(window, template, cv2.TM_CCOEFF_NORMED)
    return np.nan_to_num(scores, nan=0.0, posinf=0.0, neginf=0.0)


@dataclass
class NCCScoreMapMeasurer:
    """Dense NCC detector around the prior, with an online template.

    Parameters
    ----------
    margin
        Search window = prior box grown by this many box sizes on each side.
    learning_rate
        Template running-average rate per frame while confident.
    learn_above
        Minimum peak NCC score at the estimate for the template to learn.
    """

    margin: float = 1.0
    learning_rate: float = 0.05
    learn_above: float = 0.6

    def initialize(self, frame: Frame, box: Box) -> None:
        self.box_size_ = (max(2, int(round(box.w))), max(2, int(round(box.h))))
        self.template_ = self._patch(frame.image, box)
        self.initial_template_ = self.template_.copy()
        self.last_peak_ = 1.0

    def _patch(self, image: np.ndarray, box: Box) -> np.ndarray:
        """The grey ``(h, w) float32`` patch of ``box`` (only those pixels are converted)."""
        w, h = self.box_size_
        x = int(np.clip(round(box.x), 0, image.shape[1] - w))
        y = int(np.clip(round(box.y), 0, image.shape[0] - h))
        return to_gray(image[y:y + h, x:x + w])

    def measure(self, frame: Frame, prior: Estimate) -> ScoreMap | None:
        W, H = frame.width, frame.height
        w, h = self.box_size_
        if w >= W or h >= H:
            return None
        centre = prior.box.center
        search_box = Box.from_center(centre[0], centre[1], w, h)
        region = search_window(search_box, self.margin, W, H)
        x0, y0, x1, y1 = window_pixels(region, w, h, W, H)   # only the search window is converted to grey
        scores, origin = _ncc(to_gray(frame.image[y0:y1, x0:x1]), self.template_), (float(x0), float(y0))
        peak = float(scores.max()) if scores.size else 0.0
        self.last_peak_ = peak
        shown = Box(origin[0], origin[1], scores.shape[1] + w, scores.shape[0] + h)
        return ScoreMap(scores=scores, origin=origin, step=1.0, box_size=(float(w), float(h)),
                        quality=float(np.clip(peak, 0.0, 1.0)), search_region=shown,
                        stages={"score_map": scores})

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        if posterior.status != "tracking" or self.last_peak_ < self.learn_above:
            return
        patch = self._patch(frame.image, posterior.box)
        self.template_ = (1 - self.learning_rate) * self.template_ + self.learning_rate * patch
        # Anchor to the first appearance so drift cannot run away.
        self.template_ = 0.9 * self.template_ + 0.1 * self.initial_template_
