"""Several targets on one video: one tracker per target, stepped side by side, aware of each other.

Every target has its own :class:`~vidtrack.tracker.Tracker` (measurer, filter,
appearance model) and a stable positive ID.  Each decoded frame is shared:
the trackers predict and measure on it at the same time in a thread pool
(the compiled kernels of ``mil`` and the OpenCV calls release the GIL, so
two cores do two targets' work at once), then the measurements are resolved
against each other on the calling thread, the filters are updated, and the
measurers learn, again in the pool.

Why the targets must know about each other: independent trackers of
look-alike objects swap or merge identities where paths cross, because
while one object covers another, the hidden object's measurer finds the
occluder (the best match in its search region), its filter takes it, and its
appearance model learns it.  The interaction here is a gated nearest-
neighbour association on the trackers' own outputs (no detector is needed):

1. **Motion gate.**  With ``p_k`` the prior (predicted) box of target ``k``
   and ``m_i`` target ``i``'s measured box, while ``p_i`` overlaps ``p_j``
   the measurement is dropped when it moved from ``p_i`` towards ``p_j`` by
   more than ``pull_gate`` box scales (the projection of ``c(m_i) - c(p_i)``
   on the direction of ``c(p_j) - c(p_i)``, over ``s(p_i) = sqrt(w h)``: the
   signature of a measurer drawn onto its neighbour), or when it overlaps
   ``p_j`` and lies nearer to it, ``|c(m_i) - c(p_j)| / s(p_j) <
   |c(m_i) - c(p_i)| / s(p_i)``.  Target ``i``'s filter then predicts only
   (``update(None)``): it coasts on its motion model through the crossing.
   This is the gated nearest-neighbour association of tracking with several
   targets (Bar-Shalom & Fortmann, *Tracking and Data Association*), with
   one measurement per tracker.  A target whose prior is ``lost`` is
   searching (its measurer may re-detect far from the prediction): the gate
   does not apply to it, rule 2 does.
2. **One object, one target.**  Two kept measurements that overlap by more
   than ``duplicate_iou`` are one object: the target whose prior it is nearer
   keeps it; within ``tie`` of each other, the measurement of higher quality
   (the measurer's own appearance score) wins.
3. **Appearance held while crowded.**  A target whose box overlaps another
   target's box, or whose measurement was dropped, has its measurer's
   ``learn`` called with the posterior marked ``lost``, unmeasured and of
   quality 0 (confidence 0): every vidtrack measurer learns nothing from it (``mil``'s SVM and
   correlation filter, mean-shift's size, the score-map templates) but keeps
   its own bookkeeping (``mil`` knows it is coasting), so no appearance model
   learns the other object's pixels.  Measurers that learn inside
   ``measure`` (OpenCV's own trackers) cannot be held.

The thresholds are fractions of the box, never pixels.  They were set on
generated crossing clips (``tests/crossing_clip.py`` at seeds 100-102; the
reported seeds are 0-2), not on benchmark sequences: real crowds with
non-linear motion may need other values, and long occlusions defeat any
one-frame rule.

With one target nothing of this runs: :meth:`MultiTargetTracker.step` is
:meth:`Tracker.step <vidtrack.tracker.Tracker.step>` itself, so a one-target
run gives exactly the boxes of a single tracker.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Callable, Collection, Iterable, Mapping, TypeVar

import numpy as np

from .tracker import Tracker, make_state
from .types import LOST, Box, Estimate, Frame, Measurement, TrackState

__all__ = ["InteractionConfig", "MultiTargetTracker", "resolve_measurements", "box_iou", "overlapping_targets"]

_T = TypeVar("_T")


@dataclass(frozen=True)
class InteractionConfig:
    """How the targets of one video take each other into account."""

    aware: bool = True
    """Resolve the measurements against each other and hold learning while crowded (False: independent trackers)."""
    resolve: bool = True
    """Drop measurements that belong to another target (rules 1 and 2)."""
    hold_learning: bool = True
    """Hold a crowded target's appearance learning (rule 3)."""
    duplicate_iou: float = 0.5
    """Two measured boxes overlapping by more than this IoU are one object: one target keeps it."""
    tie: float = 0.1
    """Normalised distances closer than this are a tie, decided by the measurement's quality."""
    pull_gate: float = 0.1
    """While priors overlap, a measurement moved more than this many box scales towards the other is dropped."""


def box_iou(a: Box, b: Box) -> float:
    """Intersection over union of two boxes (0 when either is empty)."""
    x0, y0 = max(a.x, b.x), max(a.y, b.y)
    x1, y1 = min(a.x + a.w, b.x + b.w), min(a.y + a.h, b.y + b.h)
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    union = a.w * a.h + b.w * b.h - inter
    return float(inter / union) if union > 0 else 0.0


def _distance(box: Box, prior: Box) -> float:
    """``|c(box) - c(prior)| / sqrt(w h)`` of the prior: how far a measurement lies from a prediction."""
    return float(np.linalg.norm(box.center - prior.center) / max(prior.scale, 1e-9))


def _pull(box: Box, prior: Box, other: Box) -> float:
    """How far ``box`` lies from ``prior`` towards ``other``'s centre, in box scales of ``prior``."""
    towards = other.center - prior.center
    length = float(np.linalg.norm(towards))
    if length < 1e-9:
        return _distance(box, prior)
    return float((box.center - prior.center) @ towards / length / max(prior.scale, 1e-9))


def resolve_measurements(priors: Mapping[int, Box], measured: Mapping[int, Box | None],
                         quality: Mapping[int, float], config: InteractionConfig = InteractionConfig(),
                         searching: Collection[int] = ()) -> dict[int, str]:
    """The targets whose measurement is dropped, each with the reason (the module's rules 1 and 2).

    Parameters
    ----------
    priors
        Target ID -> its predicted box on this frame.
    measured
        Target ID -> the box its measurer found (None: no box).
    quality
        Target ID -> the measurement's quality in [0, 1] (the measurer's appearance score).
    config
        The thresholds.
    searching
        Targets whose prior is ``lost``: their measurement is a search for the
        target, not a step from a trusted prediction, so the motion gate
        (rule 1) does not apply to it; rule 2 does.

    Returns
    -------
    dict
        Target ID -> ``"pulled towards target J"``, ``"nearer target J"`` or
        ``"same object as target J"``, for the dropped ones only.  Pure: the
        inputs are not modified.
    """
    dropped: dict[int, str] = {}
    own = {i: _distance(b, priors[i]) for i, b in measured.items() if b is not None}
    for i in sorted(own):
        if i in searching:
            continue
        box = measured[i]
        pulled = [j for j in sorted(priors) if j != i and box_iou(priors[i], priors[j]) > 0
                  and _pull(box, priors[i], priors[j]) > config.pull_gate]
        if pulled:
            dropped[i] = f"pulled towards target {pulled[0]}"
            continue
        for j in sorted(priors):
            if j != i and box_iou(box, priors[j]) > 0 and _distance(box, priors[j]) < own[i]:
                dropped[i] = f"nearer target {j}"
                break
    kept = [i for i in sorted(own) if i not in dropped]
    for a_index, i in enumerate(kept):
        for j in kept[a_index + 1:]:
            if i in dropped or j in dropped or box_iou(measured[i], measured[j]) <= config.duplicate_iou:
                continue
            if abs(own[i] - own[j]) <= config.tie:
                loser = j if quality.get(i, 0.0) >= quality.get(j, 0.0) else i
            else:
                loser = j if own[i] < own[j] else i
            dropped[loser] = f"same object as target {i if loser == j else j}"
    return dropped


def overlapping_targets(boxes: Mapping[int, Box]) -> set[int]:
    """The IDs whose box overlaps another target's box."""
    ids = sorted(boxes)
    return {i for i in ids for j in ids if i != j and box_iou(boxes[i], boxes[j]) > 0}


class MultiTargetTracker:
    """Steps one :class:`~vidtrack.tracker.Tracker` per target on each shared frame (see the module).

    Parameters
    ----------
    trackers
        Target ID (a positive int) -> its tracker; targets are reported in
        ascending ID order.  A tracker without ``filter`` and ``measurer``
        (anything with ``initialize`` and ``step``) is stepped on its own:
        such targets run side by side but cannot take each other into account.
    config
        The interaction between targets.
    workers
        Threads stepping the targets (default: the number of targets, at most
        the number of CPUs); 1 steps them one after the other.  A runtime
        choice: the boxes do not depend on it.

    Attributes
    ----------
    seconds
        Wall-clock time spent tracking so far (all targets together).
    states_
        Target ID -> its last :class:`~vidtrack.types.TrackState`.
    dropped_
        Target ID -> why its measurement was dropped on the last frame.
    held_
        The targets whose learning was held on the last frame.
    """

    def __init__(self, trackers: Mapping[int, Tracker], *, config: InteractionConfig = InteractionConfig(),
                 workers: int | None = None) -> None:
        self.trackers = {int(i): trackers[i] for i in sorted(trackers)}
        self.config = config
        self.workers = workers
        self.seconds = 0.0
        self.states_: dict[int, TrackState] = {}
        self.dropped_: dict[int, str] = {}
        self.held_: set[int] = set()
        self._pool: ThreadPoolExecutor | None = None

    @property
    def ids(self) -> list[int]:
        """The target IDs, ascending."""
        return list(self.trackers)

    @property
    def name(self) -> str:
        """The trackers' name (``mil`` ...)."""
        names = sorted({t.name for t in self.trackers.values()})
        return ",".join(names)

    # -- running in the pool

    def _map(self, function: Callable[[int], _T], ids: Iterable[int]) -> dict[int, _T]:
        ids = list(ids)
        workers = self.workers or min(len(self.trackers), os.cpu_count() or 1)
        if workers <= 1 or len(ids) <= 1:
            return {i: function(i) for i in ids}
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="vidtrack-target")
        futures = {i: self._pool.submit(function, i) for i in ids}
        return {i: future.result() for i, future in futures.items()}

    def close(self) -> None:
        """End the worker threads (after the steps in progress); safe to call twice."""
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True)

    def __enter__(self) -> "MultiTargetTracker":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- the steps

    def initialize(self, frame: Frame, boxes: Mapping[int, Box]) -> dict[int, TrackState]:
        """Start every target on its box in ``frame``; the first states (each holding its box)."""
        if sorted(int(i) for i in boxes) != self.ids:
            raise ValueError(f"boxes for targets {sorted(boxes)}, trackers for {self.ids}")
        start = time.perf_counter()
        states = self._map(lambda i: self.trackers[i].initialize(frame, boxes[i]), self.ids)
        self.seconds += time.perf_counter() - start
        return self._keep(states)

    def step(self, frame: Frame) -> dict[int, TrackState]:
        """Track every target on ``frame``: predict and measure in parallel, resolve, update, learn."""
        start = time.perf_counter()
        if len(self.trackers) == 1:
            (i, tracker), = self.trackers.items()
            states = {i: tracker.step(frame)}
        elif not all(hasattr(t, "filter") and hasattr(t, "measurer") for t in self.trackers.values()):
            states = self._map(lambda i: self.trackers[i].step(frame), self.ids)   # opaque trackers: independent
        else:
            states = self._step_all(frame)
        self.seconds += time.perf_counter() - start
        return self._keep(states)

    def predict_only(self, frame: Frame) -> dict[int, TrackState]:
        """Every filter predicts and takes no measurement (a frame that did not decode); nobody learns."""
        start = time.perf_counter()
        states = {}
        for i, tracker in self.trackers.items():
            prior = tracker.filter.predict()
            states[i] = make_state(frame.index, prior, None, tracker.filter.update(None))
        self.seconds += time.perf_counter() - start
        return self._keep(states)

    def _step_all(self, frame: Frame) -> dict[int, TrackState]:
        def look(i: int) -> tuple[Estimate, Measurement | None]:
            tracker = self.trackers[i]
            prior = tracker.filter.predict()
            return prior, tracker.measurer.measure(frame, prior)

        looked = self._map(look, self.ids)
        measurements = {i: m for i, (_, m) in looked.items()}
        self.dropped_ = {}
        if self.config.aware and self.config.resolve:
            self.dropped_ = resolve_measurements(
                {i: prior.box for i, (prior, _) in looked.items()},
                {i: getattr(m, "box", None) for i, m in measurements.items()},
                {i: float(getattr(m, "quality", 0.0)) for i, m in measurements.items() if m is not None},
                self.config, searching={i for i, (prior, _) in looked.items() if prior.status == LOST})
        posteriors = {i: self.trackers[i].filter.update(None if i in self.dropped_ else measurements[i])
                      for i in self.ids}
        self.held_ = set()
        if self.config.aware and self.config.hold_learning:
            self.held_ = overlapping_targets({i: p.box for i, p in posteriors.items()}) | set(self.dropped_)
        teach = {i: replace(p, status=LOST, confidence=0.0, scalars={**p.scalars, "measured": 0.0, "quality": 0.0})
                 if i in self.held_ else p for i, p in posteriors.items()}
        self._map(lambda i: self.trackers[i].measurer.learn(frame, teach[i]), self.ids)
        states = {}
        for i in self.ids:
            state = make_state(frame.index, looked[i][0], measurements[i], posteriors[i])
            if i in self.held_:   # the measurement is still shown (stages), but the filter did not take it
                state = replace(state, scalars={**state.scalars, "measurement_dropped": float(i in self.dropped_),
                                                "learning_held": 1.0})
            states[i] = state
        return states

    def _keep(self, states: dict[int, TrackState]) -> dict[int, TrackState]:
        self.states_ = {i: states[i] for i in self.ids}
        return dict(self.states_)
