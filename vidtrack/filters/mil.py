"""Multiple Instance Filtering (Wnuk & Soatto): the Kalman filter on the box.

Model (sec. 1.2, eqs. 2 and 8 of the paper)::

    x(t+1) = F x(t) + v(t),          x = [c, v_c, d, v_d]   (centre, its velocity, size, its rate)
    h(y(t)_{i in O(t)}) = C x(t) + n(t)                  (centroid and extent of the inliers)

``F`` is block-diagonal constant velocity and ``C`` picks ``c`` and ``d``.
The state here is stored axis-major, ``[c_x, v_cx, c_y, v_cy, d_w, v_dw,
d_h, v_dh]`` (a permutation of the paper's ordering), so that
:func:`vidtrack.filters.kalman.motion_model` builds ``F``, ``Q`` and ``C``;
prediction and the Joseph-form update are
:func:`~vidtrack.filters.kalman.kf_predict` and
:func:`~vidtrack.filters.kalman.kf_update`.  The measurement side (SLIC
superpixels, Pegasos SVM, graph-cut inliers ``O(t)``, and the extensions)
is :class:`vidtrack.measure.mil_fusion.MILMeasurer`; this module never looks at
pixels.  No usable measurement means predict only and status ``lost``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import option
from ..types import LOST, TRACKING, Box, Estimate, Frame, Measurement
from .calibration import LostRule, load_calibration
from .confidence_cues import POSITION_CUES, RUNNING_CUES, VERIFICATION_CUES, RunningCues, border_cues, verification_cues
from .kalman import kf_predict, kf_update, motion_model

# ------------------------------------------------------------------ pure maths


def mil_motion_model(box_scale: float, *, q_centre: float, q_size: float):
    """``(F, Q, C)`` for the axis-major state ``[c_x, v_cx, c_y, v_cy, d_w, v_dw, d_h, v_dh]``.

    Constant velocity on all four axes; the velocity of the centre takes a
    random step of standard deviation ``q_centre * s`` per frame, that of the
    size ``q_size * s`` (``s`` the box scale ``sqrt(w h)``).
    """
    F, Q, C = motion_model("cv", q=1.0, n_axes=4)
    scale = np.repeat([(q_centre * box_scale) ** 2] * 2 + [(q_size * box_scale) ** 2] * 2, 2)
    return F, Q * scale[:, None], C


def state_from_box(box: Box) -> np.ndarray:
    """``x`` with zero velocities for ``box``."""
    cx, cy = box.center
    return np.array([cx, 0.0, cy, 0.0, box.w, 0.0, box.h, 0.0])


def box_from_state(x: np.ndarray, *, min_size: float = 4.0) -> Box:
    """The box ``[c, d]`` of a state (size floored at ``min_size``)."""
    return Box.from_center(x[0], x[2], max(x[4], min_size), max(x[6], min_size))


#: The calibrated confidence's cues: (name, value when missing, lower, upper); see :meth:`MILKalmanFilter.update`
CUES = (
    ("measured", 0.0, 0.0, 1.0),
    ("quality", 0.0, 0.0, 1.0),
    ("psr", 0.0, 0.0, 30.0),
    ("svm_margin", -1.0, -3.0, 3.0),
    ("inlier_coverage", 0.0, 0.0, 1.5),
    ("motion", 6.0, 0.0, 10.0),
    ("scale_change", 0.0, 0.0, 2.0),
    ("coast", 0.0, 0.0, 6.0),
    ("present", 0.0, 0.0, 1.0),
    ("cue_agreement", 1.0, 0.0, 2.0),
    # mil's verification matches the box at its own size only (no ``size_factors``): no ``verify_size_gap``
    *(cue for cue in VERIFICATION_CUES if cue[0] != "verify_size_gap"),
    *RUNNING_CUES,
    *POSITION_CUES,
)

#: Occlusion reasoning (:meth:`MILKalmanFilter._occlusion`): a frame is wholly visible when its inlier coverage
#: reaches this fraction of the running level
VISIBLE_ABOVE = 0.9
#: Weight of the past in the running levels of the inlier coverage and of the innovation's length
COVERAGE_MEMORY = 0.9
#: Occlusions are reasoned about only while the running innovation length (Mahalanobis) is below this: the
#: motion is then predictable enough for the prediction to carry the box
OCCLUSION_MOTION = 0.4



def running_level(level: float | None, value: float) -> float:
    """Exponential running mean with weight :data:`COVERAGE_MEMORY` on the past (``value`` itself at first)."""
    return value if level is None else COVERAGE_MEMORY * level + (1.0 - COVERAGE_MEMORY) * value

# ------------------------------------------------------------------ the filter


@dataclass(frozen=True)
class KalmanConfig:
    """The Kalman filter on the box (:class:`MILKalmanFilter`); noise in fractions of the box scale ``sqrt(w h)``."""

    q_centre: float = option(0.1, "process noise of the centre velocity per frame")
    q_size: float = option(0.01, "process noise of the size velocity per frame")
    r_centre: float = option(0.08, "measurement noise of the centre at quality 1 (divided by sqrt(quality))")
    r_size: float = option(0.05, "measurement noise of the size at quality 1 (divided by sqrt(quality))")
    initial_sigma: float = option(0.05, "initial standard deviation of the centre and size")
    lost_below: float = option(0.15, "measurements of lower quality are not used (predict only, lost)")
    gate: float = option(25.0, "squared Mahalanobis distance of the centre innovation beyond which a measurement "
                               "is rejected (predict only, lost)")
    coast_damping: float = option(0.5, "factor on the velocities per frame without a measurement (1: constant "
                                       "velocity)")
    size_limits: tuple[float, float] = option((0.25, 4.0), "the size stays within these multiples of the initial "
                                                           "size")
    size_damping: float = option(0.9, "factor on the size velocities at every prediction (1: the paper's "
                                      "constant rate)")
    occlusion_below: float | None = option(0.5, "a measurement whose inlier coverage falls below this fraction of "
                                                "its running level (the target partly hidden) is not used: the box "
                                                "is predicted from the last wholly visible frame at constant "
                                                "velocity and nothing is learned (none: no occlusion reasoning)")
    occlusion_frames: int = option(7, "frames an occlusion may last: then measurements are used again whatever "
                                      "their coverage, and the velocities decay by coast_damping")
    occlusion_onset: int = option(8, "an occlusion is a coverage fall from a wholly visible frame within this many "
                                     "frames (a slower fall is a change of appearance)")
    confidence: str | None = option("mil", "calibrated confidence: the cues mapped to P(IoU > 0.5) by "
                                           "vidtrack/filters/calibration/<name>.json, lost when its P(IoU > 0) "
                                           "stays below its threshold (none: the measurement's quality, lost "
                                           "when not measured)")


class MILKalmanFilter:
    """Kalman filter on ``x = [c, v_c, d, v_d]`` fed by superpixel-inlier measurements.

    The size velocity decays by ``size_damping`` at every prediction (1: the
    paper's constant-velocity ``F``): a constant size rate learned from a
    few frames of scale change otherwise keeps shrinking or growing the box
    after the change has stopped (measured sizes equal to the prediction
    give no innovation to stop it).  Without a measurement the velocities
    decay by ``coast_damping``: a long coast on a velocity learned just
    before a loss carries the prediction away more often than it carries it
    through an occlusion.

    Parameters
    ----------
    config
        The filter's :class:`KalmanConfig`.
    """

    def __init__(self, config: KalmanConfig = KalmanConfig()) -> None:
        self.config = config

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        c = self.config
        self.calibration_ = None if c.confidence is None else load_calibration(c.confidence)
        self.lost_rule_ = None if self.calibration_ is None else LostRule(self.calibration_)
        self.unmeasured_run_ = 0
        self.running_ = RunningCues()
        self.coverage_level_: float | None = None
        self.occluded_run_ = 0
        self.visible_: tuple[np.ndarray, np.ndarray] | None = None
        self.motion_level_: float | None = None
        self.since_visible_ = 0
        self.scale_ = box.scale
        self.F_, self.Q_, self.C_ = mil_motion_model(self.scale_, q_centre=c.q_centre, q_size=c.q_size)
        self.x_ = state_from_box(box)
        self.P_ = np.eye(8) * (c.initial_sigma * self.scale_) ** 2
        self.init_size_ = box.size.copy()
        self.frame_size_ = None if frame is None else (frame.width, frame.height)
        self.estimate_ = Estimate(box, self.C_ @ self.P_ @ self.C_.T, 1.0, TRACKING)

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def _box(self) -> Box:
        return box_from_state(self.x_)

    def _predicted(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One prediction of ``(x, P)``: ``x = F x``, ``P = F P F' + Q``, the size rates damped."""
        x, P = kf_predict(x, P, self.F_, self.Q_)
        x[[5, 7]] *= self.config.size_damping
        return x, P

    def predict(self) -> Estimate:
        self.x_, self.P_ = self._predicted(self.x_, self.P_)
        self._clamp()
        self.estimate_ = Estimate(self._box(), self.C_ @ self.P_ @ self.C_.T,
                                  self.estimate_.confidence, self.estimate_.status)
        return self.estimate_

    def _clamp(self) -> None:
        lo, hi = self.config.size_limits
        for k, axis in ((4, 0), (6, 1)):
            self.x_[k] = np.clip(self.x_[k], lo * self.init_size_[axis], hi * self.init_size_[axis])
        if self.frame_size_ is not None:
            self.x_[0] = np.clip(self.x_[0], 0.0, self.frame_size_[0])
            self.x_[2] = np.clip(self.x_[2], 0.0, self.frame_size_[1])

    def _coast(self) -> None:
        self.x_[[1, 3, 5, 7]] *= self.config.coast_damping

    def _occlusion(self, coverage: float | None) -> bool:
        """Whether this frame is taken for a partial occlusion (its measurement then unused).

        Occlusion reasoning from the paper's inlier set ``O(t)`` (Wnuk &
        Soatto, sec. 1.2): an occluder hides part of the target, so the graph
        cut finds inliers on a shrinking share of the box, and their centroid
        (and the correlation peak on the visible part) lag behind the target.
        An occlusion begins when a usable measurement's coverage falls below
        ``occlusion_below`` of its running level within ``occlusion_onset``
        frames of the last wholly visible one, while the motion has been
        predictable (running innovation length below :data:`OCCLUSION_MOTION`).
        The frames measured since that visible one were already pulled back:
        the state returns to it and is predicted forward at constant velocity.
        The prediction then carries the box until a measurement's coverage
        recovers or ``occlusion_frames`` frames pass.
        """
        c = self.config
        self.since_visible_ += 1
        hidden = (coverage is not None and c.occlusion_below is not None and self.coverage_level_ is not None
                  and coverage < c.occlusion_below * self.coverage_level_)
        if self.occluded_run_:
            self.occluded_run_ += 1
            if self.occluded_run_ <= c.occlusion_frames and (coverage is None or hidden):
                return True
            self.occluded_run_ = 0
            return False
        if (not hidden or self.visible_ is None or self.motion_level_ is None
                or self.motion_level_ >= OCCLUSION_MOTION or self.since_visible_ > c.occlusion_onset):
            return False
        x, P = self.visible_
        for _ in range(self.since_visible_):
            x, P = self._predicted(x, P)
        self.x_, self.P_ = x, P
        self._clamp()
        self.visible_ = None   # the next occlusion begins after a wholly visible frame
        self.occluded_run_ = 1
        return True

    def _remember_measured(self, coverage: float | None, motion: float) -> None:
        """After an update: the running levels of the coverage and the motion, and the last wholly visible state."""
        self.motion_level_ = running_level(self.motion_level_, motion)
        if coverage is None:
            return
        if self.coverage_level_ is None or coverage >= VISIBLE_ABOVE * self.coverage_level_:
            self.visible_ = (self.x_.copy(), self.P_.copy())
            self.since_visible_ = 0
        self.coverage_level_ = running_level(self.coverage_level_, coverage)

    def measurement_noise(self, quality: float) -> np.ndarray:
        """``R`` at measurement ``quality``: ``diag(r_c, r_c, r_d, r_d)^2 s^2 / quality``."""
        s = self.scale_
        c = self.config
        r = np.array([c.r_centre, c.r_centre, c.r_size, c.r_size]) * s
        return np.diag(r ** 2) / max(quality, 0.05)

    def update(self, measurement: Measurement | None) -> Estimate:
        """Kalman update with a usable, gated measurement; the confidence and status from the cues.

        ``scalars`` carry the cues of the calibrated confidence
        (:mod:`vidtrack.filters.calibration`): ``measured`` (the update
        happened), ``quality`` (the measurement's), ``psr`` (the correlation
        filter's target-only peak-to-sidelobe ratio), ``svm_margin`` (mean SVM
        score of the inliers), ``inlier_coverage`` (their share of the box),
        ``cue_agreement`` (distance from the correlation peak to the inliers'
        centre, in box sizes), ``motion`` (the
        innovation's Mahalanobis length), ``scale_change`` (``|log|`` of the
        measured over the predicted area), ``coast`` (``log(1 + n)``, ``n``
        frames without an update), ``present``, ``unmeasured`` (1 when the
        measurer returned nothing at all; narrower than ``measured`` = 0,
        which a gated or too weak measurement also gives) and, when the measurer adds
        the first frame's appearance verification map, its cues at the
        updated box and their running averages
        (:mod:`vidtrack.filters.confidence_cues`: ``verify``, ``verify_gap``,
        ``colour``, ``verify_mean``, ``colour_mean``), and ``border_gap``, the
        box's distance to the frame's edge in box sizes.  The status follows the
        calibration's :class:`~vidtrack.filters.calibration.LostRule` (the
        presence below its threshold for some frames in a row); no
        measurement at all (``None``) is ``lost`` at once.
        """
        prior_box = self._box()
        box = None if measurement is None else measurement.box
        quality = 0.0 if measurement is None else float(measurement.quality)
        stages = {} if measurement is None else measurement.stages
        scalars: dict[str, float] = {"quality": quality}
        for cue in ("psr", "inlier_coverage", "cue_agreement"):
            if cue in stages:
                scalars[cue] = float(stages[cue])
        if measurement is not None and len(measurement.inliers):
            scalars["inlier_count"] = float(np.sum(measurement.inliers))
            if np.any(measurement.inliers):
                scalars["svm_margin"] = float(np.mean(measurement.scores[measurement.inliers]))
        status = LOST
        if box is not None:
            scalars["scale_change"] = float(abs(np.log(max(box.area, 1e-6) / max(prior_box.area, 1e-6))))
        usable = box is not None and quality >= self.config.lost_below
        occluded = self._occlusion(scalars.get("inlier_coverage") if usable else None)
        scalars["occluded"] = float(occluded)
        if usable and not occluded:
            z = np.array([*box.center, box.w, box.h])
            R = self.measurement_noise(quality)
            y = z[:2] - self.x_[[0, 2]]
            S = (self.C_ @ self.P_ @ self.C_.T + R)[:2, :2]
            d2 = float(y @ np.linalg.solve(S, y))
            scalars["innovation"] = float(np.linalg.norm(y))
            scalars["motion"] = float(np.sqrt(max(d2, 0.0)))
            if d2 <= self.config.gate:
                result = kf_update(self.x_, self.P_, z, self.C_, R)  # Joseph form
                self.x_, self.P_ = result.x, result.P
                self._clamp()
                status = TRACKING
        scalars["measured"] = float(status == TRACKING)
        self.unmeasured_run_ = 0 if status == TRACKING else self.unmeasured_run_ + 1
        scalars["coast"] = float(np.log1p(self.unmeasured_run_))
        present = bool(getattr(measurement, "present", False))
        scalars["present"] = float(present)
        if status == TRACKING:
            self._remember_measured(scalars.get("inlier_coverage"), scalars["motion"])
        if status == LOST and not occluded:
            self._coast()
            quality = min(quality, self.config.lost_below * 0.99)
            if present:   # predicted only, but the target is there: not lost
                status = TRACKING
        reported = self._box()
        verification = verification_cues(stages, reported.center)   # empty without the verification map
        scalars.update(verification)
        scalars.update(self.running_.update(verification))
        scalars.update(border_cues(reported, self.frame_size_))
        scalars["unmeasured"] = float(measurement is None)   # nothing at all (the search left the frame): lost
        confidence = float(np.clip(quality, 0.0, 1.0))
        if self.calibration_ is not None:
            confidence = self.calibration_.probability(scalars)
            status = LOST if self.lost_rule_.lost(scalars) else TRACKING
        cov = self.C_ @ self.P_ @ self.C_.T
        self.estimate_ = Estimate(reported, cov, confidence, status, scalars)
        return self.estimate_
