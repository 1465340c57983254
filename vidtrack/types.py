"""Frozen value types that flow through the vidtrack pipeline.

The data path (see ``DESIGN.md`` of the project)::

    FrameSource --Frame--> Tracker.step(frame)
        prior = filter.predict()                # Estimate
        m     = measurer.measure(frame, prior)  # a Measurement kind, or None
        post  = filter.update(m)                # Estimate (m None: predict only)
        measurer.learn(frame, post)
    --TrackState--> sinks

Conventions
-----------
* Boxes are ``x, y, w, h`` floats with a top-left origin in 0-based pixel
  coordinates (OpenCV's).
* Images are ``(H, W, 3) uint8`` BGR arrays, as OpenCV decodes them.
* Stage images (back-projection, score map, superpixel labels ...) stored in
  :attr:`TrackState.stages` cover :attr:`TrackState.search_region` (the array
  is the search region resampled to the array's shape) unless their name ends
  in ``_full`` (then they cover the whole frame).  Point sets (particles,
  detections) are ``(N, 3)`` float arrays ``[x, y, weight]`` in frame
  coordinates.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Literal, Mapping

import numpy as np

Status = Literal["tracking", "lost"]
TRACKING: Status = "tracking"
LOST: Status = "lost"

#: What separates the numbers of a box in text: commas, tabs, spaces or semicolons, in any mix.
_SEPARATORS = re.compile(r"[,\s;]+")

#: A box lies (mostly) inside a frame when at least this fraction of its area does.
INSIDE_FRACTION = 0.5


def split_numbers(text: str) -> list[str]:
    """The fields of ``text`` separated by commas, tabs, spaces or semicolons (empty fields dropped)."""
    return [part for part in _SEPARATORS.split(text) if part]


@dataclass(frozen=True)
class Box:
    """Axis-aligned box ``(x, y, w, h)``, top-left origin, float pixels."""

    x: float
    y: float
    w: float
    h: float

    @classmethod
    def from_center(cls, cx: float, cy: float, w: float, h: float) -> "Box":
        """Box with centre ``(cx, cy)`` and size ``(w, h)``."""
        return cls(float(cx - w / 2.0), float(cy - h / 2.0), float(w), float(h))

    @classmethod
    def from_array(cls, values) -> "Box":
        """Box from any 4-sequence ``x, y, w, h``."""
        x, y, w, h = (float(v) for v in values)
        return cls(x, y, w, h)

    @classmethod
    def parse(cls, text: str) -> "Box":
        """Box from the text ``x,y,w,h``: the command line's ``--init-box`` and every row of a box file.

        The four numbers may be separated by commas, tabs, spaces or
        semicolons (the separators found in benchmark ground-truth files).
        Values are not checked: ``nan`` or a zero size parse (a ground-truth
        row "not annotated"); see :meth:`is_valid`.

        Raises
        ------
        ValueError
            ``not four numbers: '...'`` when a field is not a number,
            ``expected 4 numbers x,y,w,h, got N`` when there are not four.
        """
        parts = split_numbers(text)
        try:
            values = [float(part) for part in parts]
        except ValueError:
            raise ValueError(f"not four numbers: {text.strip()[:60]!r}") from None
        if len(values) != 4:
            raise ValueError(f"expected 4 numbers x,y,w,h, got {len(values)}")
        return cls(*values)

    @property
    def center(self) -> np.ndarray:
        """Centre ``(cx, cy)`` as a float array of shape (2,)."""
        return np.array([self.x + self.w / 2.0, self.y + self.h / 2.0])

    @property
    def size(self) -> np.ndarray:
        """Size ``(w, h)`` as a float array of shape (2,)."""
        return np.array([self.w, self.h])

    @property
    def area(self) -> float:
        return max(self.w, 0.0) * max(self.h, 0.0)

    @property
    def scale(self) -> float:
        """``sqrt(area)`` (at least 1): the box's linear size, the unit of the filters' noise parameters."""
        return float(np.sqrt(max(self.area, 1.0)))

    def as_array(self) -> np.ndarray:
        """``[x, y, w, h]`` float array."""
        return np.array([self.x, self.y, self.w, self.h], dtype=float)

    def as_int_rect(self) -> tuple[int, int, int, int]:
        """Rounded ``(x, y, w, h)`` ints, as OpenCV's trackers want them."""
        return (int(round(self.x)), int(round(self.y)), max(1, int(round(self.w))), max(1, int(round(self.h))))

    def scaled(self, factor: float) -> "Box":
        """Same centre, size multiplied by ``factor``."""
        cx, cy = self.center
        return Box.from_center(cx, cy, self.w * factor, self.h * factor)

    def clipped(self, width: int, height: int) -> "Box":
        """Intersection with the image ``[0, width) x [0, height)`` (may be empty)."""
        x0, y0 = max(self.x, 0.0), max(self.y, 0.0)
        x1, y1 = min(self.x + self.w, float(width)), min(self.y + self.h, float(height))
        return Box(x0, y0, max(x1 - x0, 0.0), max(y1 - y0, 0.0))

    def is_valid(self) -> bool:
        """True when the box has finite coordinates and positive size."""
        return bool(np.all(np.isfinite(self.as_array())) and self.w > 0 and self.h > 0)

    def is_inside(self, width: int, height: int) -> bool:
        """True when the box lies mostly inside a ``width x height`` frame.

        "Mostly" is at least :data:`INSIDE_FRACTION` of its area: an init box
        may stick out of the frame a little, never mostly.
        """
        return self.clipped(width, height).area >= INSIDE_FRACTION * self.area

    def __str__(self) -> str:
        return f"{self.x:.2f},{self.y:.2f},{self.w:.2f},{self.h:.2f}"


@dataclass(frozen=True)
class Frame:
    """One decoded frame: ``index`` (0-based) and ``image`` ``(H, W, 3) uint8`` BGR.

    ``timestamp`` is the source's presentation time in seconds (a video's or
    a stream's clock; None for image folders), ``arrival`` the
    :func:`time.monotonic` second at which a live source received the frame
    (None for files): latency is measured from it.
    """

    index: int
    image: np.ndarray
    timestamp: float | None = None
    arrival: float | None = None

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        return int(self.image.shape[1])


# --------------------------------------------------------------------------
# Measurements.  Every kind carries ``stages`` (named arrays the sinks may
# show), the search region it looked in, and a ``quality`` in [0, 1] that a
# filter may use for its confidence and for gating.
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class PointMeasurement:
    """A measured point ``z`` with covariance ``R`` (e.g. a mean-shift box centre).

    ``box`` is the measured box when the measurer has one (its centre is ``z``
    for box-centre measurements).
    """

    z: np.ndarray
    R: np.ndarray
    box: Box | None = None
    quality: float = 1.0
    search_region: Box | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ScoreMap:
    """Dense detector scores over box positions.

    ``scores[i, j]`` is the score of the box of size ``box_size`` whose
    top-left corner is at ``origin + (j, i) * step`` (x along columns).
    Higher is better; scores are normalised to about ``[-1, 1]`` (e.g. NCC).
    """

    scores: np.ndarray
    origin: tuple[float, float]
    step: float
    box_size: tuple[float, float]
    quality: float = 1.0
    search_region: Box | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)

    def box_at(self, row: float, col: float) -> Box:
        """The box whose top-left corner is at map cell ``(row, col)``."""
        return Box(
            self.origin[0] + col * self.step,
            self.origin[1] + row * self.step,
            self.box_size[0],
            self.box_size[1],
        )

    def best_box(self) -> Box:
        """The box of the map's highest score (the first on ties)."""
        row, col = np.unravel_index(int(np.argmax(self.scores)), np.shape(self.scores))
        return self.box_at(row, col)

    def centers(self) -> np.ndarray:
        """Box centres of every cell, shape ``(H, W, 2)`` ``[cx, cy]``."""
        rows, cols = np.indices(self.scores.shape, dtype=float)
        cx = self.origin[0] + cols * self.step + self.box_size[0] / 2.0
        cy = self.origin[1] + rows * self.step + self.box_size[1] / 2.0
        return np.stack([cx, cy], axis=-1)


@dataclass(frozen=True)
class Detections:
    """Unassociated detections: clutter and drop-outs allowed.

    ``points`` ``(N, 2)`` centres, ``scores`` ``(N,)``, optional ``boxes``
    ``(N, 4)`` ``[x, y, w, h]``.  ``N`` may be zero.
    """

    points: np.ndarray
    scores: np.ndarray
    boxes: np.ndarray | None = None
    quality: float = 1.0
    search_region: Box | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Superpixels:
    """Superpixels of a search region with per-superpixel scores and inliers.

    ``labels`` ``(h, w) int`` covers ``search_region``; ``features``
    ``(K, D)``; ``scores`` ``(K,)`` classifier scores; ``inliers`` ``(K,)``
    bool; ``box`` the box measured from the inliers (None when there are none);
    ``present``: another cue of the measurer (``mil``'s correlation filter)
    sees the target at the predicted box although the frame gives no usable
    measurement (the filter then predicts only, but does not call it lost).
    """

    labels: np.ndarray
    features: np.ndarray
    scores: np.ndarray
    inliers: np.ndarray
    box: Box | None = None
    quality: float = 1.0
    search_region: Box | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)
    present: bool = False


Measurement = PointMeasurement | ScoreMap | Detections | Superpixels


@dataclass(frozen=True)
class Estimate:
    """A filter's belief: ``box`` with an optional state ``covariance``.

    ``confidence`` in ``[0, 1]`` and ``status`` are the filter's own judgement
    of the estimate; ``scalars`` are filter-specific numbers worth plotting
    (innovation, covariance trace, c_t ...); ``stages`` are the filter's own
    intermediate arrays (e.g. ``particles``), merged into the
    :class:`TrackState` beside the measurer's.
    """

    box: Box
    covariance: np.ndarray | None = None
    confidence: float = 1.0
    status: Status = TRACKING
    scalars: Mapping[str, float] = field(default_factory=dict)
    stages: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrackState:
    """What one tracker step produced for one frame; the sinks' input."""

    index: int
    box: Box
    confidence: float
    status: Status
    predicted: Box | None = None
    measured: Box | None = None
    search_region: Box | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)
    scalars: Mapping[str, float] = field(default_factory=dict)
