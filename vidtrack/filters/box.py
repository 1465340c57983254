"""Box-level filters built on point-state cores (Kalman, IMM, SVK ...).

:class:`CentreFilter` tracks the box centre with any *core* that quacks like
:class:`~vidtrack.filters.kalman.KalmanFilter` (``initialize(x0, P0)``,
``predict()``, ``update(z, R)``, ``x_``, ``P_``) over an axis-major state
``[p_x, (v_x, a_x), p_y, (v_y, a_y)]`` with ``order`` entries per axis.  The
box size follows the accepted measurements.  A measurement of quality below
``lost_below`` marks the target ``lost``; below ``reject_below`` it is not
used at all (predict only).  While no measurement is used the derivative
states decay by ``coast_damping`` per frame and the centre is kept inside the
frame, so during an occlusion the box coasts on the motion model without
flying off.

:class:`PassThroughFilter` is "no filter": the estimate is the last accepted
measurement (the plain mean-shift tracker's implicit constant-position model).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from ..types import LOST, TRACKING, Box, Detections, Estimate, Frame, Measurement, ScoreMap


def measurement_box(measurement: Measurement | None) -> Box | None:
    """The box a measurement carries, if any."""
    return None if measurement is None else getattr(measurement, "box", None)


class CentreFilter:
    """Filter the box centre with a point-state core; see the module docstring.

    Parameters
    ----------
    make_core
        ``make_core(box) -> core``: builds the core for the init box (its
        noise levels usually scale with the box size).
    order
        State entries per axis in the core (1 drift, 2 CV, 3 CA).
    initial_sigma
        Initial position standard deviation, as a fraction of the box size;
        derivatives start at the same spread per frame.
    lost_below
        Below this measurement quality the status is ``lost``.
    reject_below
        Below this quality the measurement is not used (predict only);
        defaults to ``lost_below`` (a measurement that says "lost" is not trusted).
    coast_damping
        Factor applied to the derivative states per frame without a measurement.
    """

    def __init__(self, make_core: Callable[[Box], object], *, order: int, initial_sigma: float = 0.1,
                 lost_below: float = 0.4, reject_below: float | None = None, coast_damping: float = 0.9) -> None:
        self.make_core = make_core
        self.order = order
        self.initial_sigma = initial_sigma
        self.lost_below = lost_below
        self.reject_below = lost_below if reject_below is None else reject_below
        self.coast_damping = coast_damping

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self.core_ = self.make_core(box)
        x0 = np.zeros(2 * self.order)
        x0[0], x0[self.order] = box.center
        spread = (self.initial_sigma * float(np.mean(box.size))) ** 2
        self.core_.initialize(x0, np.eye(2 * self.order) * spread)
        self.size_ = box.size.copy()
        self.frame_size_ = None if frame is None else (frame.width, frame.height)
        self.estimate_ = Estimate(box, self._position_cov(), 1.0, TRACKING)

    def _position_cov(self) -> np.ndarray:
        idx = [0, self.order]
        return self.core_.P_[np.ix_(idx, idx)]

    def _box(self) -> Box:
        return Box.from_center(self.core_.x_[0], self.core_.x_[self.order], *self.size_)

    def _coast(self) -> None:
        """No measurement used: damp the derivatives, keep the centre in the frame."""
        x = self.core_.x_.copy()
        for axis in range(2):
            start = axis * self.order
            x[start + 1:start + self.order] *= self.coast_damping
            if self.frame_size_ is not None:
                x[start] = np.clip(x[start], 0.0, self.frame_size_[axis])
        self.core_.x_ = x
        for f in getattr(self.core_, "filters", ()):  # an IMM's model-matched filters too
            f.x_ = x.copy()

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def predict(self) -> Estimate:
        self.core_.predict()
        self.estimate_ = Estimate(self._box(), self._position_cov(), self.estimate_.confidence,
                                  self.estimate_.status)
        return self.estimate_

    def update(self, measurement: Measurement | None) -> Estimate:
        box = measurement_box(measurement)
        quality = 0.0 if measurement is None else float(measurement.quality)
        scalars: dict[str, float] = {}
        if box is None or quality < self.reject_below:
            self._coast()
            status = LOST
        else:
            z = getattr(measurement, "z", None)
            z = box.center if z is None else z
            R = getattr(measurement, "R", None)
            if R is None:
                R = np.eye(2) * (0.1 * float(np.mean(box.size))) ** 2
            result = self.core_.update(np.asarray(z, float), np.asarray(R, float))
            innovation = getattr(result, "innovation", None)
            if innovation is not None:
                scalars["innovation"] = float(np.linalg.norm(innovation))
            self.size_ = box.size.copy()
            status = TRACKING if quality >= self.lost_below else LOST
        self.estimate_ = Estimate(self._box(), self._position_cov(), quality, status, scalars)
        return self.estimate_


class PassThroughFilter:
    """No filtering: the estimate is the last accepted measurement's box.

    Parameters
    ----------
    lost_below
        Below this measurement quality the status is ``lost``.
    follow_when_lost
        Take the measured box even when its quality says ``lost`` (for
        trackers such as OpenCV's whose box is their own best guess); if
        False the last good box is kept.
    """

    def __init__(self, *, lost_below: float = 0.6, follow_when_lost: bool = False) -> None:
        self.lost_below = lost_below
        self.follow_when_lost = follow_when_lost

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self.estimate_ = Estimate(box, None, 1.0, TRACKING)

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def predict(self) -> Estimate:
        return self.estimate_

    def update(self, measurement: Measurement | None) -> Estimate:
        box = measurement_box(measurement)
        quality = 0.0 if measurement is None else float(measurement.quality)
        if box is None:
            self.estimate_ = Estimate(self.estimate_.box, None, quality, LOST)
        elif quality < self.lost_below:
            self.estimate_ = Estimate(box if self.follow_when_lost else self.estimate_.box, None, quality, LOST)
        else:
            self.estimate_ = Estimate(box, None, quality, TRACKING)
        return self.estimate_


def measured_size(measurement: Measurement | None, centre: np.ndarray) -> np.ndarray | None:
    """The box size ``(w, h)`` a measurement states near ``centre``, if it states one.

    A :class:`~vidtrack.types.ScoreMap` states its ``box_size``;
    :class:`~vidtrack.types.Detections` the box of the detection nearest
    ``centre``; measurements carrying a ``box`` its size.
    """
    if measurement is None:
        return None
    if isinstance(measurement, ScoreMap):
        return np.asarray(measurement.box_size, float)
    if isinstance(measurement, Detections):
        if measurement.boxes is None or len(measurement.points) == 0:
            return None
        nearest = int(np.argmin(np.linalg.norm(np.asarray(measurement.points, float) - centre, axis=1)))
        return np.asarray(measurement.boxes[nearest, 2:], float)
    box = measurement_box(measurement)
    return None if box is None else box.size


class MeasuredSizeFilter:
    """A centre filter whose box takes its size from the measurements (composition, one level deep).

    The inner filter tracks the centre (NormalHedge, particle, grid Bayes,
    CBT keep the init box size); this wrapper replaces the size of every
    estimate by the last size the measurements stated while the inner
    filter was ``tracking``, blended at ``rate`` per frame (1: the measured
    size).  The scale-searching correlation-filter detector makes those
    filters follow the target's size.
    """

    def __init__(self, inner, *, rate: float = 1.0) -> None:
        self.inner = inner
        self.rate = rate

    def _sized(self, estimate: Estimate) -> Estimate:
        cx, cy = estimate.box.center
        self.estimate_ = replace(estimate, box=Box.from_center(cx, cy, *self.size_))
        return self.estimate_

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self.inner.initialize(box, frame)
        self.size_ = box.size.copy()
        self._sized(self.inner.estimate)

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def predict(self) -> Estimate:
        return self._sized(self.inner.predict())

    def update(self, measurement: Measurement | None) -> Estimate:
        estimate = self.inner.update(measurement)
        if estimate.status == TRACKING:
            size = measured_size(measurement, estimate.box.center)
            if size is not None and np.all(np.isfinite(size)) and np.all(size > 0):
                self.size_ = (1.0 - self.rate) * self.size_ + self.rate * size
        return self._sized(estimate)
