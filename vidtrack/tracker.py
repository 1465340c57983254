"""The per-frame step loop: ``predict -> measure -> update -> learn``, and what a recipe is.

A *recipe* is a name users type (``--filter kalman-cv``) mapped to a factory
that builds a :class:`Tracker` from a measurer and a filter, and the frozen
configuration it builds from.  Recipes live in the modules of
:mod:`vidtrack.recipes`, one per family; :func:`vidtrack.recipes.registry`
merges them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np

from .types import Box, Estimate, Frame, Measurement, TrackState


@runtime_checkable
class Measurer(Protocol):
    """Turns a frame and the filter's prior into a measurement."""

    def initialize(self, frame: Frame, box: Box) -> None:
        """Learn the initial appearance from ``box`` in ``frame``."""

    def measure(self, frame: Frame, prior: Estimate) -> Measurement | None:
        """Measure in ``frame`` around ``prior``; None when nothing was found."""

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        """Update the appearance model after the filter's update (may do nothing)."""


@runtime_checkable
class Filter(Protocol):
    """A (robust) recursive estimator of the target box."""

    def initialize(self, box: Box, frame: Frame) -> None:
        """Start from ``box`` in ``frame``."""

    def predict(self) -> Estimate:
        """Propagate the belief one frame; return the prior."""

    def update(self, measurement: Measurement | None) -> Estimate:
        """Fold in ``measurement`` (None: predict only); return the posterior."""

    @property
    def estimate(self) -> Estimate:
        """The current belief (read-only)."""


class Tracker:
    """Runs ``predict -> measure -> update -> learn`` on each frame.

    Parameters
    ----------
    measurer, filter
        Any objects following :class:`Measurer` and :class:`Filter`.
    name
        The recipe name, for display.
    """

    def __init__(self, measurer: Measurer, filter: Filter, name: str = "") -> None:
        self.measurer = measurer
        self.filter = filter
        self.name = name

    def initialize(self, frame: Frame, box: Box) -> TrackState:
        """Initialise on the first frame; the returned state holds ``box`` itself."""
        self.measurer.initialize(frame, box)
        self.filter.initialize(box, frame)
        return TrackState(index=frame.index, box=box, confidence=1.0, status="tracking", measured=box)

    def step(self, frame: Frame) -> TrackState:
        """Track one frame and return its :class:`TrackState`."""
        prior = self.filter.predict()
        measurement = self.measurer.measure(frame, prior)
        posterior = self.filter.update(measurement)
        self.measurer.learn(frame, posterior)
        return make_state(frame.index, prior, measurement, posterior)


def make_state(index: int, prior: Estimate, measurement: Measurement | None, posterior: Estimate) -> TrackState:
    """Assemble the :class:`TrackState` of one step (shared by all trackers)."""
    stages: dict[str, Any] = {}
    measured = search_region = None
    if measurement is not None:
        stages.update(measurement.stages)
        measured = getattr(measurement, "box", None)
        search_region = measurement.search_region
    stages.update(posterior.stages)
    scalars = dict(posterior.scalars)
    scalars.setdefault("confidence", float(posterior.confidence))
    if posterior.covariance is not None:
        scalars.setdefault("covariance_trace", float(np.trace(posterior.covariance)))
    return TrackState(
        index=index,
        box=posterior.box,
        confidence=float(np.clip(posterior.confidence, 0.0, 1.0)),
        status=posterior.status,
        predicted=prior.box,
        measured=measured,
        search_region=search_region,
        stages=stages,
        scalars=scalars,
    )


@dataclass(frozen=True)
class Recipe:
    """A named tracker: ``build(config, seed=...) -> Tracker``.

    ``description`` is the one line ``vidtrack filters`` shows; ``config`` is
    the family's frozen configuration (:mod:`vidtrack.config`) with this
    recipe's values, None for a tracker without options.  A preset is a
    recipe with the same ``build`` and another ``config``.
    """

    description: str
    build: Callable[..., Tracker]
    config: Any = None
