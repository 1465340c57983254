"""Channel-Based Tracking of the box centre on video, from unassociated detections.

Felsberg & Larsson, "Learning Object Tracking in Image Sequences" /
"Channel-Based Tracking": the belief about the position is a cos² channel
vector (:mod:`vidtrack.channels`), predicted by the learned transition and
updated with the channel-encoded detections (eq. 10)::

    w_{k|k-1} = F w_{k-1|k-1}
    w_{k|k}   = h(z_k) . w_{k|k-1} / h(z_k)' w_{k|k-1}

and the transition is learned by the normalised covariance of consecutive
channel vectors (eq. 11).  :class:`CBTFilter` applies this to the centre of a
box on a grid that follows the target (a window a fixed number of box sizes
wide, so its cost follows the box, not the frame), with a motion model in units of the box
that it learns while tracking or reads from a :class:`~vidtrack.filters.cbt_model.CBTModel`.
The detections come from :class:`~vidtrack.measure.detections.DetectionMeasurer`
(the ``cbt`` recipe, :mod:`vidtrack.recipes.channels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..channels import (ChannelBasis, conditional_from_counts, current_marginal, decode_nd, decode_nd_modes,
                        diagonal_history, displacement_counts, embedded_predict, encode, history_prior, normalized,
                        position_conditional, random_walk_displacement, shift_tensor)
from ..errors import UsageError
from ..types import LOST, TRACKING, Box, Detections, Estimate, Frame, Measurement
from .calibration import LostRule, load_calibration
from .cbt_model import CBTModel
from .confidence_cues import POSITION_CUES, RUNNING_CUES, VERIFICATION_CUES, RunningCues, border_cues, verification_cues
from .channels import mean_field_update, product_likelihood

#: The calibrated confidence's cues: (name, value when missing, lower, upper); see :class:`CBTFilter`
CUES = (
    ("measured", 0.0, 0.0, 1.0),
    ("raw_confidence", 0.0, 0.0, 1.0),
    ("mode_mass", 0.0, 0.0, 1.0),
    ("best_near", 0.0, 0.0, 1.0),
    ("modes", 0.0, 0.0, 10.0),
    ("detections", 0.0, 0.0, 10.0),
    ("quality", 0.0, 0.0, 1.0),
    ("psr", 0.0, 0.0, 30.0),
    ("motion", 0.0, 0.0, 2.0),
    ("coast", 0.0, 0.0, 6.0),
    *VERIFICATION_CUES,
    *RUNNING_CUES,
    *POSITION_CUES,
)

#: Largest memory, in MB, the position grid's transition tensors may take (both axes, with the temporaries
#: of building them); a configuration needing more is refused when the filter starts.
MEMORY_BUDGET_MB = 512.0


def grid_megabytes(channels: int, order: int) -> float:
    """MB of one axis' transition tensor ``G`` (``channels^(order+1)`` floats) with the temporaries building it."""
    return 3 * 8 * float(channels) ** (order + 1) / 2 ** 20


def window_layout(extent: float, spacing: float, window: float, centre: float) -> tuple[int, int]:
    """Channel count and first lattice index ``k`` (grid origin ``k * spacing``) of one axis.

    The position grid covers ``[0, extent]`` when ``window >= extent``
    (``k = 0``), otherwise ``window`` pixels on the lattice of multiples of
    ``spacing``, centred on ``centre`` as closely as the lattice allows and
    kept inside ``[0, extent]``.
    """
    if window >= extent:
        return ChannelBasis.with_spacing(0.0, float(extent), spacing).n, 0
    n = max(4, int(np.ceil(window / spacing)) + 3)
    k_max = max(0, int(np.floor((extent - (n - 3) * spacing) / spacing)))
    k = int(np.clip(np.round((centre - 0.5 * (n - 3) * spacing) / spacing), 0, k_max))
    return n, k


@dataclass
class CBTFilter:
    """Channel-based tracking of the box centre from unassociated detections (eq. 10).

    State: the box centre on a cos² channel grid with spacing
    ``spacing_boxes`` box sizes but at least ``min_spacing`` px, over a
    window ``window_boxes`` box sizes (at least ``min_window`` px) wide
    around the target, or the whole frame when that is smaller.  The window
    moves with the estimate by whole channels: the transition is
    translation-invariant, so moving it only shifts the history tensors
    (mass beyond the window, far from the target, is dropped).  Memory and
    time per frame therefore follow the box, never the frame; a
    configuration whose grid would exceed ``MEMORY_BUDGET_MB`` is refused
    when the filter starts (a UsageError).  Each axis carries an order-``order`` embedded Markov
    model (state = the last ``order`` positions); the joint of the current
    centre is the product of the axis marginals (mean field), the 2-D update
    with the detections is exact and its result is re-factorised
    (:func:`~vidtrack.filters.channels.mean_field_update`).  The transition
    is a translation-invariant displacement model (box units) mapped onto
    the grid by :func:`~vidtrack.channels.position_conditional`; it starts
    as a random walk of ``prior_sigma`` box sizes and is learned online by
    the covariance estimate (eq. 11) from the filter's own decoded estimates
    while tracking (``prior_weight`` pseudo-counts of the random walk), or is
    given by ``model``.

    Likelihood ``h``: ``clutter + sum_d s_d b(x - x_d) b(y - y_d)`` with
    ``s_d = exp((score_d - top) / score_temperature)``, ``top`` the frame's
    best score (``relative_scores``) or 1.  Relative scores keep the
    measurement informative when the detector's scores drop everywhere
    (appearance change); the confidence still uses the absolute scores.

    Confidence: the posterior mass of the decoded mode's ``3x3`` window
    (scaled so ``mass_full`` counts as 1) times the best detection score
    within a quarter box of it; ``lost`` below ``lost_below``.  The reported
    confidence is, with ``confidence`` set, the calibrated probability that
    the box overlaps the target by more than 0.5
    (:mod:`vidtrack.filters.calibration`) from the cues :data:`CUES`,
    among them the first-frame verification of the box
    (:mod:`vidtrack.filters.confidence_cues`), and the reported status is
    the calibration's (:class:`~vidtrack.filters.calibration.LostRule`):
    ``lost`` once that probability has stayed below the file's
    ``lost_below`` for its ``lost_after`` frames in a row, or at once on a
    frame the filter does not measure (its own confidence below
    ``lost_below``, the ``unmeasured`` cue).  The reported ``lost`` widens
    the detector's search and stops its learning.  On a frame it does not
    measure the box is the prediction, the history is reset to the current
    position (``coast_when_lost``: the learned velocity is forgotten so the
    box does not run off during an occlusion) and nothing is learned.

    Parameters
    ----------
    order
        Markov order of the motion model (positions in the state).
    spacing_boxes, min_spacing
        Position grid spacing in box sizes, and its lower bound in pixels.
    window_boxes, min_window
        Side of the position grid in box sizes, and its lower bound in pixels.
    d_channels, d_range
        Channels of the displacement model and the largest displacement per
        frame it represents, in box sizes.
    prior_sigma
        Standard deviation of the random-walk prior, box sizes per frame.
    prior_weight
        Pseudo-counts of the random-walk prior in the online estimate.
    relearn_every
        Tracked frames between re-estimates of the online model.
    clutter
        Likelihood floor (clutter and missed detections).
    score_temperature
        Temperature of the detection weights ``s_d``.
    product
        ``"plain"`` or ``"sqrt"`` (square-root) product in the update.
    learn_online
        Learn the motion model while tracking (without ``model``).
    lost_below
        Own confidence below which a frame is not measured (the box is the prediction; the frame is ``lost``).
    mass_full
        Mode mass that counts as a fully confident mode.
    model
        A learned :class:`~vidtrack.filters.cbt_model.CBTModel` (its order
        must be ``order``); None: the random walk, learned online.
    mode_threshold
        Mass a posterior mode must hold to be counted in the ``modes`` scalar.
    coast_when_lost
        Forget the learned velocity on a frame that is not measured.
    relative_scores
        Weigh detections relative to the frame's best score.
    confidence
        Name of the calibrated confidence (``vidtrack/filters/calibration/<name>.json``, from the cues
        :data:`CUES`; ``"cbt"`` was fitted on the correlation filter's detections, and its lost rule gives
        the status); None: the confidence above, and ``lost`` below ``lost_below``.
    """

    order: int = 2
    spacing_boxes: float = 0.2
    min_spacing: float = 2.0
    window_boxes: float = 10.0
    min_window: float = 64.0
    d_channels: int = 15
    d_range: float = 1.0
    prior_sigma: float = 0.2
    prior_weight: float = 20.0
    relearn_every: int = 10
    clutter: float = 0.02
    score_temperature: float = 0.05
    product: str = "plain"
    learn_online: bool = True
    lost_below: float = 0.2
    mass_full: float = 0.5
    model: CBTModel | None = None
    mode_threshold: float = 0.05
    coast_when_lost: bool = True
    relative_scores: bool = True
    confidence: str | None = "cbt"

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        width = frame.width if frame is not None else int(box.x + 4 * box.w)
        height = frame.height if frame is not None else int(box.y + 4 * box.h)
        self.size_ = box.size.copy()
        self.scale_ = box.scale
        self.spacing_ = spacing = float(max(self.spacing_boxes * self.scale_, self.min_spacing))
        self.window_ = float(max(self.window_boxes * self.scale_, self.min_window))
        self.frame_size_ = (width, height)
        centre = box.center
        layouts = [window_layout(extent, spacing, self.window_, c) for extent, c in zip(self.frame_size_, centre)]
        needed = sum(grid_megabytes(n, self.order) for n, _ in layouts)
        if needed > MEMORY_BUDGET_MB:
            raise UsageError(f"cbt: a position grid of {layouts[0][0]}x{layouts[1][0]} channels of order "
                             f"{self.order} needs {needed:.0f} MB, over the {MEMORY_BUDGET_MB:.0f} MB budget; "
                             f"raise grid.spacing_boxes or lower grid.window_boxes or order")
        self.origin_ = [k for _, k in layouts]
        self.bases_ = tuple(self._basis(n, k) for n, k in layouts)
        if self.model is not None:
            if self.model.order != self.order:
                raise UsageError(f"the CBT model has order {self.model.order}, the filter {self.order}")
            self.d_basis_ = self.model.basis
            self.D_ = [self.model.Dx, self.model.Dy]
        else:
            self.d_basis_ = ChannelBasis(-self.d_range, self.d_range, self.d_channels)
            self.D_ = [random_walk_displacement(self.d_basis_, self.prior_sigma, self.order)] * 2
        self.prior_D_ = list(self.D_)
        self.counts_ = [np.zeros_like(D) for D in self.D_]
        self.G_ = [position_conditional(D, self.d_basis_, b, self.scale_) for D, b in zip(self.D_, self.bases_)]
        # First-frame prior: the initial centre over the whole history.
        self.W_ = [history_prior(encode(centre[axis], b), self.order) for axis, b in enumerate(self.bases_)]
        self.history_ = [centre.copy()]
        self.since_learn_ = 0
        self.prior_box_ = box
        self.calibration_ = None if self.confidence is None else load_calibration(self.confidence)
        self.lost_rule_ = None if self.calibration_ is None else LostRule(self.calibration_)
        self.unmeasured_run_ = 0
        self.running_ = RunningCues()
        self.estimate_ = Estimate(box, None, 1.0, TRACKING, {})

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def _basis(self, n: int, k: int) -> ChannelBasis:
        return ChannelBasis(k * self.spacing_, (k + n - 3) * self.spacing_, n)

    def _follow(self, centre: np.ndarray) -> None:
        """Move each axis' window by whole channels so it is centred on ``centre`` (a no-op on a whole-frame grid)."""
        for axis in range(2):
            n, k = window_layout(self.frame_size_[axis], self.spacing_, self.window_, float(centre[axis]))
            shift = k - self.origin_[axis]
            if shift:
                self.W_[axis] = normalized(shift_tensor(self.W_[axis], shift))
                self.origin_[axis] = k
        self.bases_ = tuple(self._basis(b.n, k) for b, k in zip(self.bases_, self.origin_))

    def _box_at(self, centre: np.ndarray) -> Box:
        return Box.from_center(float(centre[0]), float(centre[1]), *self.size_)

    def _prior_joint(self) -> np.ndarray:
        """Mean-field joint ``(C_x, C_y)`` of the current centre: the outer product of the axis marginals."""
        m = [current_marginal(W) for W in self.W_]
        return np.multiply.outer(m[0], m[1])

    def _to_frame(self, t: np.ndarray) -> np.ndarray:
        return np.array([self.bases_[0].from_channel(t[0]), self.bases_[1].from_channel(t[1])])

    def predict(self) -> Estimate:
        self._follow(self.estimate_.box.center)
        self.W_ = [embedded_predict(W, G) for W, G in zip(self.W_, self.G_)]  # w_{k|k-1} = F w_{k-1|k-1}
        t, mass = decode_nd(self._prior_joint())
        self.prior_box_ = self._box_at(np.clip(self._to_frame(t), 0.0, np.asarray(self.frame_size_, float)))
        self.estimate_ = Estimate(self.prior_box_, None, self.estimate_.confidence,
                                  self.estimate_.status, {"mode_mass": mass})
        return self.estimate_

    def likelihood(self, detections: Detections) -> np.ndarray:
        """``h(z)`` over the current-centre channel grid ``(C_x, C_y)`` (:func:`~vidtrack.filters.channels.product_likelihood`)."""
        s = None
        if len(detections.points):
            scores = np.asarray(detections.scores, float)
            top = float(scores.max()) if self.relative_scores else 1.0
            s = np.exp((scores - top) / self.score_temperature)
        return product_likelihood(detections.points, self.bases_, weights=s, clutter=self.clutter)

    def update(self, measurement: Measurement | None) -> Estimate:
        scalars: dict[str, float] = {}
        has_dets = isinstance(measurement, Detections) and len(measurement.points) > 0
        if has_dets:  # eq. 10 on the mean-field joint, re-factorised into the axes' history tensors
            self.W_, post, evidence = mean_field_update(self.W_, self.likelihood(measurement), self.product)
            scalars["evidence"] = float(evidence)
        else:
            post = self._prior_joint()
        scalars["detections"] = float(len(measurement.points)) if isinstance(measurement, Detections) else 0.0
        n_modes = len(decode_nd_modes(post, self.mode_threshold))
        t, mass = decode_nd(post)
        centre = np.clip(self._to_frame(t), 0.0, np.asarray(self.frame_size_, float))
        best_near = 0.0
        if has_dets:
            d = np.linalg.norm(np.asarray(measurement.points, float) - centre, axis=1)
            near = d <= 0.25 * self.scale_ + max(b.spacing for b in self.bases_)
            if near.any():
                best_near = float(np.max(np.asarray(measurement.scores, float)[near]))
        confidence = float(np.clip(min(1.0, mass / self.mass_full) * best_near, 0.0, 1.0))
        status = TRACKING if confidence >= self.lost_below else LOST
        scalars.update(mode_mass=mass, best_near=best_near, modes=float(n_modes))
        if status == TRACKING:
            self.history_.append(centre.copy())
            self.history_ = self.history_[-(self.order + 1):]
            if self.learn_online and self.model is None:
                self._learn()
        else:
            self.history_ = [centre.copy()]  # a gap breaks the displacement chain
            if self.coast_when_lost:  # forget the velocity: the history repeats the current position
                self.W_ = [diagonal_history(current_marginal(W), self.order) for W in self.W_]
        box = self._box_at(centre) if status == TRACKING else self.prior_box_  # lost: the prediction
        confidence = self._calibrated(measurement, box, confidence, status, scalars)
        if self.lost_rule_ is not None:   # the reported status: the calibration's lost rule
            status = LOST if self.lost_rule_.lost(scalars) else TRACKING
        self.estimate_ = Estimate(box, None, confidence, status, scalars)
        return self.estimate_

    def _calibrated(self, measurement: Measurement | None, box: Box, raw: float, status: str,
                    scalars: dict[str, float]) -> float:
        """Add the cues :data:`CUES` to ``scalars``; the calibrated probability (``raw`` without a calibration).

        ``status`` is the filter's own (its uncalibrated confidence below
        ``lost_below``): a frame it does not measure sets the ``unmeasured`` cue.
        """
        measured = status == TRACKING
        self.unmeasured_run_ = 0 if measured else self.unmeasured_run_ + 1
        stages = getattr(measurement, "stages", None) or {}
        scalars.update(measured=float(measured), unmeasured=float(not measured), raw_confidence=raw,
                       quality=0.0 if measurement is None else float(getattr(measurement, "quality", 0.0)),
                       coast=float(np.log1p(self.unmeasured_run_)),
                       motion=float(np.linalg.norm(box.center - self.estimate_.box.center) / max(self.scale_, 1e-9)))
        if "psr" in stages:
            scalars["psr"] = float(stages["psr"])
        scalars.update(verification_cues(stages, box.center))
        scalars.update(self.running_.update(scalars))
        scalars.update(border_cues(box, self.frame_size_))
        if self.calibration_ is None:
            return raw
        return self.calibration_.probability(scalars)

    def _learn(self) -> None:
        """Online covariance estimate (eq. 11) of the displacement model from the decoded centres."""
        if len(self.history_) < self.order + 1:
            return
        track = np.asarray(self.history_[-(self.order + 1):])
        for axis in range(2):
            self.counts_[axis] += displacement_counts(track[:, axis], self.d_basis_, self.scale_, self.order)
        self.since_learn_ += 1
        if self.since_learn_ >= self.relearn_every:
            self.since_learn_ = 0
            self.D_ = [conditional_from_counts(c, p, self.prior_weight) for c, p in zip(self.counts_, self.prior_D_)]
            self.G_ = [position_conditional(D, self.d_basis_, b, self.scale_) for D, b in zip(self.D_, self.bases_)]
