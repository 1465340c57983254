"""OpenCV's trackers as vidtrack recipes (``opencv-mil``, ``opencv-kcf`` ...), for comparison in one tool.

The estimate is OpenCV's own box; the confidence and the ``lost`` status are
vidtrack's (see :mod:`vidtrack.measure.opencv_trackers`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ..config import option
from ..filters.box import PassThroughFilter
from ..measure.opencv_trackers import OpenCVTrackerMeasurer
from ..tracker import Recipe, Tracker

#: Histogram similarity (to the init box or the running reference, the better) below which an OpenCV box counts as lost.
LOST_BELOW = 0.5

DESCRIPTIONS = {
    "mil": "OpenCV's MIL tracker (Babenko et al., online multiple-instance boosting)",
    "kcf": "OpenCV's KCF tracker (kernelized correlation filters)",
    "csrt": "OpenCV's CSRT tracker (discriminative correlation filter, channel and spatial reliability)",
    "tld": "OpenCV's TLD tracker (tracking-learning-detection, legacy API)",
    "medianflow": "OpenCV's MedianFlow tracker (forward-backward optical flow, legacy API)",
    "mosse": "OpenCV's MOSSE tracker (minimum output sum of squared error filter, legacy API)",
}


@dataclass(frozen=True)
class OpenCVConfig:
    """vidtrack's confidence for an OpenCV tracker's box: a colour histogram against a reference."""

    bins: int = option(8, "histogram bins per channel for the confidence")
    adapt_rate: float = option(0.05, "rate of the running-average reference histogram")
    adapt_above: float = option(0.5, "confidence a box needs to update the running reference")


def _builder(kind: str):
    def build(config: OpenCVConfig, seed=None) -> Tracker:
        return Tracker(OpenCVTrackerMeasurer(kind, seed=seed, **asdict(config)),
                       PassThroughFilter(lost_below=LOST_BELOW, follow_when_lost=True))
    return build


RECIPES = {f"opencv-{kind}": Recipe(text, _builder(kind), OpenCVConfig()) for kind, text in DESCRIPTIONS.items()}
