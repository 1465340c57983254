"""Per-frame confidence cues read at the filter's estimate from a measurement and the frame's size (no pixels).

The calibrated confidence (:mod:`vidtrack.filters.calibration`) of the
trackers on the correlation detector combines cues that each see a different
failure.  Those that need the measurement at the reported box, or the box
and the frame's size, are computed here:

* ``verify``, ``colour``: the appearance verification map
  (:mod:`vidtrack.measure.verification`, ``stages["verification"]``, a
  :class:`~vidtrack.types.ScoreMap`) read at the estimate's centre: the
  first frame's grey template NCC and colour likelihood of the reported box;
  ``verify_gap``: the map's best NCC minus the estimate's (a better match
  elsewhere in the region: the box sits beside the target);
  ``verify_size_gap``: the best NCC of a box of another size at the same
  centre (``stages["sizes"]`` of the verification map) minus the
  estimate's (a box of another size looks more like the target: the size is wrong);
* ``score_at``: the detector's score map (divided by its peak) at the
  estimate's centre, ``peak_offset`` the distance from the map's peak to
  the estimate in box sizes;
* ``log_scale``: ``|log|`` of the measured box size over the initial one;
* ``verify_mean``, ``colour_mean``: ``verify`` and ``colour`` averaged over
  the last frames (an exponential average, :class:`RunningCues`): a drift
  lasts, a single blurred or occluded frame does not;
* ``border_gap``: the filter's box's distance to the nearest edge of the
  frame, in box sizes (:func:`border_cues`; the score-map filters' and cbt's
  box keeps the first frame's size, the measured size is applied after them):
  a box that has lost its target often comes to rest against the frame's
  edge, where targets seldom are.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.ndimage import map_coordinates

from ..types import ScoreMap


#: The verification cues' rows of a tracker's cue table: (name, value when missing, lower, upper)
VERIFICATION_CUES = (
    ("verify", 0.0, -1.0, 1.0),
    ("verify_gap", 0.0, 0.0, 2.0),
    ("verify_size_gap", 0.0, -2.0, 2.0),
    ("colour", 0.5, 0.0, 1.0),
)
#: The rows of their running averages (:class:`RunningCues`)
RUNNING_CUES = (
    ("verify_mean", 0.0, -1.0, 1.0),
    ("colour_mean", 0.5, 0.0, 1.0),
)

#: The position cue's row (:func:`border_cues`); a box a box size or more from every edge has the upper bound, 1
POSITION_CUES = (
    ("border_gap", 1.0, 0.0, 1.0),
)


def map_value(scores: np.ndarray, smap: ScoreMap, centre) -> float:
    """Bilinear value of ``scores`` (the geometry of ``smap``) at the box centred on ``centre``, clamped to the map."""
    scores = np.asarray(scores, dtype=float)
    if scores.size == 0:
        return float("nan")
    col = (float(centre[0]) - smap.box_size[0] / 2.0 - smap.origin[0]) / smap.step
    row = (float(centre[1]) - smap.box_size[1] / 2.0 - smap.origin[1]) / smap.step
    row = float(np.clip(row, 0.0, scores.shape[0] - 1))
    col = float(np.clip(col, 0.0, scores.shape[1] - 1))
    return float(map_coordinates(scores, [[row], [col]], order=1, mode="nearest")[0])


def verification_cues(stages: Mapping, centre) -> dict[str, float]:
    """``verify``, ``verify_gap``, ``verify_size_gap`` and ``colour`` at ``centre`` from ``stages["verification"]``.

    Empty without a verification map.
    """
    ver = stages.get("verification")
    if not isinstance(ver, ScoreMap) or ver.scores.size == 0:
        return {}
    out = {"verify": map_value(ver.scores, ver, centre)}
    out["verify_gap"] = float(np.max(ver.scores)) - out["verify"]
    sizes = [m for m in ver.stages.get("sizes", ()) if m.scores.size]
    if sizes:
        out["verify_size_gap"] = max(map_value(m.scores, m, centre) for m in sizes) - out["verify"]
    colour = ver.stages.get("colour")
    if colour is not None:
        out["colour"] = map_value(colour, ver, centre)
    return out


def border_cues(box, frame_size) -> dict[str, float]:
    """``border_gap``: the distance from ``box`` to the nearest edge of a ``(width, height)`` frame, in box sizes.

    The box size is :attr:`~vidtrack.types.Box.scale`, ``sqrt(w h)``; a box across an edge has a gap of 0.
    Empty without a frame size.
    """
    if frame_size is None:
        return {}
    width, height = (float(v) for v in frame_size)
    x, y, w, h = (float(v) for v in box.as_array())
    gap = min(x, y, width - (x + w), height - (y + h))
    return {"border_gap": max(gap, 0.0) / box.scale}


def score_map_cues(smap: ScoreMap, centre, scale: float, init_scale: float) -> dict[str, float]:
    """``score_at``, ``peak_offset`` and ``log_scale`` of a detector's score map at ``centre``."""
    scores = np.asarray(smap.scores, dtype=float)
    if scores.size == 0:
        return {}
    peak = smap.best_box().center
    size = float(np.sqrt(max(smap.box_size[0] * smap.box_size[1], 1e-9)))
    return {"score_at": map_value(scores, smap, centre),
            "peak_offset": float(np.linalg.norm(np.asarray(centre, float) - peak) / max(scale, 1e-9)),
            "log_scale": abs(float(np.log(size / max(init_scale, 1e-9))))}


class RunningCues:
    """Exponential averages ``m <- (1 - gain) m + gain x`` of named cues; the first value starts each average."""

    def __init__(self, names: tuple[str, ...] = ("verify", "colour"), gain: float = 0.3) -> None:
        self.names = names
        self.gain = gain
        self.means_: dict[str, float] = {}

    def update(self, cues: Mapping[str, float]) -> dict[str, float]:
        """Fold in this frame's ``cues``; the averages as ``<name>_mean``."""
        for name in self.names:
            x = cues.get(name)
            if x is None or not np.isfinite(x):
                continue
            m = self.means_.get(name)
            self.means_[name] = float(x) if m is None else (1.0 - self.gain) * m + self.gain * float(x)
        return {f"{name}_mean": m for name, m in self.means_.items()}
