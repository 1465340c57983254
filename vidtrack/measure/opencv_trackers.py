"""OpenCV's own trackers wrapped as measurers, with a confidence of our own.

OpenCV's ``update`` returns an ``ok`` flag that stays True long after the
target has gone, so the wrapper judges each box itself: the confidence is the
Bhattacharyya coefficient (the similarity of Comaniciu et al., see
:mod:`vidtrack.measure.meanshift`) between the kernel-weighted histogram of
the returned box and the better of two references: the init box's histogram
and a running average of the histograms of confident boxes (so a target that
turns around is not declared lost).  It is zero when OpenCV reports failure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from ..errors import UsageError
from ..types import Box, Estimate, Frame, PointMeasurement
from .meanshift import bhattacharyya, bin_image, box_pixels, histogram_layout, is_gray, kernel_histogram


def _cv_message(exc: cv2.error) -> str:
    """The last line of an OpenCV error (its assertion), without file and line."""
    text = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
    return text.split(" error: ", 1)[-1]


def _legacy(name: str) -> Callable[[], object]:
    return lambda: getattr(cv2.legacy, name)()


#: vidtrack name -> factory of a fresh OpenCV tracker.
OPENCV_TRACKERS: dict[str, Callable[[], object]] = {
    "mil": lambda: cv2.TrackerMIL_create(),
    "kcf": lambda: cv2.TrackerKCF_create(),
    "csrt": lambda: cv2.TrackerCSRT_create(),
    "tld": _legacy("TrackerTLD_create"),
    "medianflow": _legacy("TrackerMedianFlow_create"),
    "mosse": _legacy("TrackerMOSSE_create"),
}


#: Smallest box side (pixels, after clipping to the frame) OpenCV's trackers start on: below it
#: CSRT and MOSSE fail an assertion, TLD crashes the process and MIL does not finish a frame.
MIN_SIDE = 8

#: Largest fraction of the frame's width or height the box may cover for trackers that sample
#: background around it (MIL finds no negative samples otherwise and fails an assertion; TLD
#: crashes the process on a box spanning the frame's width or height, measured on 128x96 frames).
MAX_COVER = {"mil": 0.9, "tld": 0.9}

#: Largest side ratio (long / short) per tracker: TLD crashes the process on a 100x10 box.
MAX_ASPECT = {"tld": 5.0}


#: Memory budget (MB) of OpenCV's TLD, whose detector scans the whole frame at every scale: a start
#: whose estimate (:func:`tld_megabytes`) exceeds it is refused instead of taking the machine down.
TLD_BUDGET_MB = 512.0


def tld_megabytes(box_w: int, box_h: int, width: int, height: int) -> float:
    """Estimated memory (MB) OpenCV's TLD takes on a ``width x height`` frame for a ``box_w x box_h`` box.

    ``30 MB`` per megapixel of frame plus ``0.0113 MB`` per unit of the
    frame-to-box area ratio (its scanning grid), fitted to the peak resident
    memory measured by ``scripts/bench_memory.py`` (above the interpreter's):
    155 MB for a 10x10 box on 1280x720, 305 MB for 40x40 and 1180 MB for
    10x10 on 3840x2160.
    """
    pixels = float(width) * float(height)
    return 30.0 * pixels / 1e6 + 0.0113 * pixels / max(float(box_w) * float(box_h), 1.0)


def start_rect(kind: str, box: Box, width: int, height: int) -> tuple[int, int, int, int]:
    """The integer rect OpenCV's ``kind`` tracker is started on: ``box`` clipped to the frame.

    Raises
    ------
    UsageError
        When the part of ``box`` inside the ``width`` x ``height`` frame is
        smaller than :data:`MIN_SIDE` or (MIL) leaves no background around it,
        or (TLD) would need more memory than :data:`TLD_BUDGET_MB`: one line
        instead of an OpenCV assertion, a crash, a hang or the machine's memory.
    """
    x0, y0 = max(int(round(box.x)), 0), max(int(round(box.y)), 0)
    x1, y1 = min(int(round(box.x + box.w)), width), min(int(round(box.y + box.h)), height)
    w, h = x1 - x0, y1 - y0
    if w < MIN_SIDE or h < MIN_SIDE:
        raise UsageError(f"opencv-{kind} needs a box of at least {MIN_SIDE}x{MIN_SIDE} pixels inside "
                         f"the frame, got {max(w, 0)}x{max(h, 0)}")
    cover = MAX_COVER.get(kind)
    if cover is not None and (w > cover * width or h > cover * height):
        raise UsageError(f"opencv-{kind} needs background around the box: {w}x{h} covers more than "
                         f"{cover:.0%} of the {width}x{height} frame's width or height")
    aspect = MAX_ASPECT.get(kind)
    if aspect is not None and max(w, h) > aspect * min(w, h):
        raise UsageError(f"opencv-{kind} needs a box at most {aspect:g} times longer than wide, got {w}x{h}")
    if kind == "tld" and (need := tld_megabytes(w, h, width, height)) > TLD_BUDGET_MB:
        raise UsageError(f"opencv-tld scans the whole frame: a {w}x{h} box on a {width}x{height} frame needs "
                         f"about {need:.0f} MB, over its {TLD_BUDGET_MB:.0f} MB budget; use a larger box or "
                         f"a downscaled video")
    return x0, y0, w, h


#: OpenCV trackers with random state inside OpenCV that ``--seed`` cannot reset: reproducible per
#: process only (measured: two runs in one process differ, two fresh processes agree).
NOT_REPRODUCIBLE = {"mil", "tld"}


@dataclass
class OpenCVTrackerMeasurer:
    """Runs one OpenCV tracker; each frame's box is a measurement with our own quality.

    Parameters
    ----------
    kind
        Key of :data:`OPENCV_TRACKERS`.
    seed
        Passed to ``cv2.setRNGSeed`` before initialisation.  OpenCV's MIL and
        TLD also keep random state inside OpenCV that this does not reset:
        a run is reproducible in a fresh process (every ``vidtrack`` command,
        every ``vidtrack eval`` job), but a second tracker built in the same
        process differs (see :data:`NOT_REPRODUCIBLE`).
    bins
        Histogram bins per channel for the confidence.
    adapt_rate
        Rate of the running-average reference histogram.
    adapt_above
        Confidence needed for a box to update the running reference.
    """

    kind: str
    seed: int | None = None
    bins: int = 8
    adapt_rate: float = 0.05
    adapt_above: float = 0.5

    def initialize(self, frame: Frame, box: Box) -> None:
        cv2.setRNGSeed(0 if self.seed is None else int(self.seed))
        rect = start_rect(self.kind, box, frame.width, frame.height)
        self.tracker_ = OPENCV_TRACKERS[self.kind]()
        try:
            self.tracker_.init(frame.image, rect)
        except cv2.error as exc:
            raise UsageError(f"opencv-{self.kind} cannot start on the box {box}: "
                             f"{_cv_message(exc)}") from None
        self.gray_ = is_gray(frame.image)
        self.channel_bins_, self.n_bins_ = histogram_layout(self.bins, self.gray_)
        self.reference_, _ = self._histogram(frame, box)
        self.adaptive_ = self.reference_.copy()

    def _histogram(self, frame: Frame, box: Box) -> tuple[np.ndarray, float]:
        """Kernel histogram of ``box``, binning only the pixels it covers (not the whole frame)."""
        x0, y0, x1, y1 = box_pixels(box, frame.width, frame.height)
        window = frame.image[max(y0, 0):max(y1, y0), max(x0, 0):max(x1, x0)]
        bins = bin_image(window, gray=self.gray_, bins=self.channel_bins_)
        return kernel_histogram(bins, box, self.n_bins_, origin=(x0, y0))

    def measure(self, frame: Frame, prior: Estimate) -> PointMeasurement | None:
        try:
            ok, rect = self.tracker_.update(frame.image)
        except cv2.error:  # OpenCV's assertion on a degenerate box: a missed measurement, not a crash
            return None
        if not ok:
            return None
        box = Box.from_array(rect)
        if not box.is_valid():
            return None
        hist, mass = self._histogram(frame, box)
        if mass == 0:
            return PointMeasurement(z=box.center, R=np.eye(2), box=box, quality=0.0)
        quality = max(bhattacharyya(hist, self.reference_), bhattacharyya(hist, self.adaptive_))
        if quality >= self.adapt_above:
            self.adaptive_ = (1 - self.adapt_rate) * self.adaptive_ + self.adapt_rate * hist
        return PointMeasurement(z=box.center, R=np.eye(2), box=box, quality=quality)

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        """OpenCV's trackers learn inside ``update``; nothing to do here."""
