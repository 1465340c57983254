"""Box-level filters that track the box centre on a sliding detector's :class:`~vidtrack.types.ScoreMap`.

The video counterpart of the 1-D experiment of Chaudhuri, Freund & Hsu, "An
Online Learning-based Framework for Tracking" (UAI 2010): the same score map
(scores over box positions in a search window around the prior) is read by

* :class:`NormalHedgeBoxFilter` -- the SMC NormalHedge tracker (Algorithms
  2-3, :mod:`vidtrack.filters.normalhedge`); actions are box centres and an
  action's loss is the clipped negative score of its box,
  ``l_o(x) = -q(s(x))``, ``q(s) = min(hi, max(s, lo))`` (the paper's clipped
  loss, Section 5); the dynamics function is ``F(x) = x + v`` with ``v`` a
  running average of the estimate's displacement (``velocity_gain = 0``
  gives the paper's identity ``F``);
* :class:`ParticleBoxFilter` -- a SIR particle filter
  (:mod:`vidtrack.filters.particle`) with a Gaussian random walk and the
  likelihood ``p(s | x) ∝ exp(-(1 - s(x))^2 / 2 sigma_s^2)`` (the score of
  the true box is modelled as 1 plus Gaussian noise, the analogue of the
  paper's generative model);
* :class:`GridBayesBoxFilter` -- the exact grid Bayes filter
  (:mod:`vidtrack.filters.grid_bayes`) over a grid of centres that reaches
  ``extent`` box sizes around the estimate and moves with it, with the same
  random walk and likelihood; cells outside the detector's window are given
  the score ``outside_score`` (the detector's "background").

Lengths are in box sizes, so a filter behaves alike on any frame size; the
``nh``, ``pf`` and ``bayes`` recipes (:mod:`vidtrack.recipes.normalhedge`)
set the values they use on video.  All three skip the update and report their prediction when the map's peak
score (``ScoreMap.quality``) is below ``lost_below``.  Their confidence is,
with ``confidence=None``, the weight (posterior) mass within ``radius`` box
sizes of the estimate times the peak-score quality, ``lost`` when the update
was skipped; with ``confidence="nh"`` (``"pf"``, ``"bayes"``: the recipes'
default) it is the calibrated probability that the box overlaps the target by
more than 0.5 (:mod:`vidtrack.filters.calibration`) from the cues :data:`CUES`
the calibration file names (``measured``, the map's ``quality`` and ``psr``,
the ``concentration``, the ``motion`` of the estimate in box sizes,
``mass_quality`` the uncalibrated confidence (concentration times quality),
``coast`` ``log(1 + n)`` after ``n`` skipped updates, ``spread`` the
estimate's standard deviation in box sizes, and the cues of
:mod:`vidtrack.filters.confidence_cues` read at the estimate: the first-frame
verification ``verify``, ``verify_gap``, ``verify_size_gap``, ``colour`` and
their running averages, the map's ``score_at``, ``peak_offset`` and
``log_scale``, and the box's ``border_gap`` to the frame's edge; the packaged
files use four cues each, chosen on *tune*, see ``scripts/fit_confidence.py``),
and the status is the calibration's
(:class:`~vidtrack.filters.calibration.LostRule`): ``lost`` when that
probability has stayed below the file's ``lost_below`` for its
``lost_after`` frames in a row, or when the update was skipped (the
``unmeasured`` scalar).  A ``lost`` status starts the detector's
re-detection (:mod:`vidtrack.measure.correlation_score_map`) and stops its
learning.  With ``reseed_above`` set (the ``nh``, ``pf`` and ``bayes`` recipes), a
filter whose prior is lost restarts at the map's peak when the map's quality
reaches it and the prior's own box scores under :data:`RESEED_SCORE` of the
peak: the re-detection has found the target where the filter's actions,
particles or grid mass, gathered around the prior, would not reach it.  Each
exposes (in ``Estimate.stages``) ``{"particles": (N, 3) [cx, cy, weight]}`` in frame
coordinates after every update.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from ..types import LOST, TRACKING, Box, Estimate, Frame, Measurement, ScoreMap
from .calibration import LostRule, load_calibration
from .confidence_cues import (POSITION_CUES, RUNNING_CUES, VERIFICATION_CUES, RunningCues, border_cues, score_map_cues,
                              verification_cues)
from .grid_bayes import gaussian_transition, grid_predict_separable, grid_update_log
from .normalhedge import NormalHedgeTracker, weight_concentration
from .particle import ParticleFilter, weighted_mean_cov


def score_at_centres(smap: ScoreMap, centres: np.ndarray, outside: float = 0.0) -> np.ndarray:
    """Bilinear score of the boxes centred at ``centres`` ``(K, 2)`` ``[cx, cy]``; ``outside`` off the map."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    col = (centres[:, 0] - smap.box_size[0] / 2.0 - smap.origin[0]) / smap.step
    row = (centres[:, 1] - smap.box_size[1] / 2.0 - smap.origin[1]) / smap.step
    return map_coordinates(np.asarray(smap.scores, dtype=float), [row, col], order=1, mode="constant",
                           cval=outside)


#: The calibrated confidence's cues: (name, value when missing, lower, upper); see :class:`_CentreBoxFilter`
CUES = (
    ("measured", 0.0, 0.0, 1.0),
    ("quality", 0.0, 0.0, 1.0),
    ("psr", 0.0, 0.0, 30.0),
    ("concentration", 0.0, 0.0, 1.0),
    ("motion", 0.0, 0.0, 2.0),
    ("mass_quality", 0.0, 0.0, 1.0),
    ("coast", 0.0, 0.0, 6.0),
    *VERIFICATION_CUES,
    ("score_at", 0.0, -1.0, 1.0),
    ("peak_offset", 0.0, 0.0, 3.0),
    ("log_scale", 0.0, 0.0, 2.0),
    ("spread", 2.0, 0.0, 2.0),
    *RUNNING_CUES,
    *POSITION_CUES,
)


#: A lost filter restarts at a confident re-detection only if its own box scores below this fraction of the peak.
RESEED_SCORE = 0.5


def _usable(measurement: Measurement | None, lost_below: float) -> bool:
    return (isinstance(measurement, ScoreMap) and measurement.scores.size > 0
            and float(measurement.quality) >= lost_below)


class _CentreBoxFilter:
    """Shared book-keeping: fixed box size, prediction, lost handling, stages."""

    lost_below: float
    radius: float
    reseed_above: float | None

    def _box(self, centre: np.ndarray) -> Box:
        return Box.from_center(float(centre[0]), float(centre[1]), *self.size_)

    def _keep_in_frame(self, centre: np.ndarray) -> np.ndarray:
        if self.frame_size_ is None:
            return centre
        return np.clip(centre, 0.0, np.asarray(self.frame_size_, dtype=float))

    def _start(self, box: Box, frame: Frame | None) -> None:
        """Book-keeping shared by every ``initialize``: box size, scale, frame size, the calibration."""
        self.size_ = box.size.copy()
        self.scale_ = box.scale
        self.frame_size_ = None if frame is None else (frame.width, frame.height)
        confidence = getattr(self, "confidence", None)
        self.calibration_ = None if confidence is None else load_calibration(confidence)
        self.lost_rule_ = None if self.calibration_ is None else LostRule(self.calibration_)
        self.unmeasured_run_ = 0
        self.running_ = RunningCues()

    def update(self, measurement: Measurement | None) -> Estimate:
        """The filter's own update, then the confidence and status from the cues (see the module docstring).

        When :meth:`_restarts`, the filter restarts at the map's peak before its update.
        """
        prior = self.estimate_
        if self._restarts(prior, measurement):
            self._reseed(self._keep_in_frame(measurement.best_box().center))
        estimate = self._update(measurement)
        measured = estimate.status == TRACKING
        self.unmeasured_run_ = 0 if measured else self.unmeasured_run_ + 1
        cues = {"measured": float(measured), "unmeasured": float(not measured),
                "quality": 0.0 if measurement is None else float(getattr(measurement, "quality", 0.0)),
                "coast": float(np.log1p(self.unmeasured_run_)),
                "motion": float(np.linalg.norm(estimate.box.center - prior.box.center) / max(self.scale_, 1e-9))}
        stages = getattr(measurement, "stages", None) or {}
        if "psr" in stages:
            cues["psr"] = float(stages["psr"])
        centre = estimate.box.center
        cues.update(verification_cues(stages, centre))
        cues.update(self.running_.update(cues))
        cues.update(border_cues(estimate.box, self.frame_size_))
        if isinstance(measurement, ScoreMap):
            cues.update(score_map_cues(measurement, centre, self.scale_, self.scale_))
        if estimate.covariance is not None:
            cues["spread"] = float(np.sqrt(max(np.trace(estimate.covariance), 0.0))) / max(self.scale_, 1e-9)
        if measured:
            cues["concentration"] = float(estimate.scalars.get("concentration", 0.0))
            cues["mass_quality"] = cues["concentration"] * float(np.clip(cues["quality"], 0.0, 1.0))
        estimate = dataclasses.replace(estimate, scalars={**estimate.scalars, **cues})
        if self.calibration_ is not None:
            # P(IoU > 0.5) from the cues; lost after a run of low frames, or at once when the update was skipped
            lost = self.lost_rule_.lost(cues)
            estimate = dataclasses.replace(estimate, confidence=self.calibration_.probability(cues),
                                           status=LOST if lost else TRACKING)
        self.estimate_ = estimate
        return self.estimate_

    def _restarts(self, prior: Estimate, measurement: Measurement | None) -> bool:
        """Whether a lost ``prior`` restarts at ``measurement``'s peak (``reseed_above`` set).

        The detector's re-detection found the target: a map the update will
        use, of quality at least ``reseed_above``, on which the prior's own
        box scores under :data:`RESEED_SCORE` of the peak.
        """
        if self.reseed_above is None or prior.status != LOST:
            return False
        if not _usable(measurement, max(self.reseed_above, self.lost_below)):
            return False
        own = score_at_centres(measurement, prior.box.center[None, :])[0]
        return bool(own < RESEED_SCORE * float(np.max(measurement.scores)))

    @property
    def estimate(self) -> Estimate:
        return self.estimate_

    def _lost(self, prior: Estimate, quality: float, scalars: dict) -> Estimate:
        self.estimate_ = Estimate(prior.box, prior.covariance, float(np.clip(quality, 0, 1)) * 0.5, LOST, scalars,
                                  stages=self.stages_)
        return self.estimate_


class NormalHedgeBoxFilter(_CentreBoxFilter):
    """SMC NormalHedge over box centres on a score map; see the module docstring.

    Parameters
    ----------
    n_actions
        ``N``.
    alpha
        Regret discount.
    sigma_star
        Re-sampling standard deviation (``sqrt Sigma_*``), in box sizes.
    clip
        ``(lo, hi)`` of the clipped score ``q``.
    outside_score
        Score of an action whose box lies outside the map.
    lost_below
        Peak score below which the frame is not used and the target is lost.
    radius
        Confidence radius, in box sizes.
    velocity_gain
        The dynamics function is ``F(x) = x + v`` with ``v`` a running
        average (this gain per frame) of the estimate's displacement; 0 gives
        the paper's identity ``F``.
    rng
        Random seed or Generator.
    confidence
        Name of the calibrated confidence (``vidtrack/filters/calibration/<name>.json``); None: the
        concentration times the quality, ``lost`` when the update was skipped.
    reseed_above
        While lost, restart at the map's peak when the map's quality reaches this (and the filter's own
        box scores under :data:`RESEED_SCORE` of the peak); None: never.
    """

    def __init__(self, n_actions: int = 100, alpha: float = 0.4, sigma_star: float = 0.25,
                 clip: tuple[float, float] = (-1.0, 1.0), outside_score: float = -1.0, lost_below: float = 0.35,
                 radius: float = 0.15, velocity_gain: float = 0.2, coast_damping: float = 0.5,
                 window: float = 0.0, prune_below: float = 0.3,
                 rng: np.random.Generator | int | None = None, confidence: str | None = None,
                 reseed_above: float | None = None) -> None:
        self.confidence = confidence
        self.reseed_above = reseed_above
        self.window = window
        self.prune_below = prune_below
        self.velocity_gain = velocity_gain
        self.coast_damping = coast_damping
        self.n_actions = n_actions
        self.alpha = alpha
        self.sigma_star = sigma_star
        self.clip = clip
        self.outside_score = outside_score
        self.lost_below = lost_below
        self.radius = radius
        self.rng = rng

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self._start(box, frame)
        sigma = self.sigma_star * self.scale_
        rng = np.random.default_rng(self.rng)   # one stream: the initial draw, then the tracker's re-sampling
        self.core_ = NormalHedgeTracker(self.n_actions, self.alpha, sigma, dynamics=None, rng=rng,
                                        prune_below=self.prune_below)
        self.core_.initialize(box.center + sigma * rng.standard_normal((self.n_actions, 2)))
        self.estimate_ = Estimate(box, np.eye(2) * sigma ** 2, 1.0, TRACKING)
        self.velocity_ = np.zeros(2)
        self.last_centre_ = box.center.copy()
        self.stages_ = {}

    def _reseed(self, centre: np.ndarray) -> None:
        """Restart the actions around ``centre`` (zero regret, no velocity; the random stream continues)."""
        sigma = self.sigma_star * self.scale_
        rng = self.core_.rng_
        self.core_.initialize(centre + sigma * rng.standard_normal((self.n_actions, 2)))
        self.core_.rng_ = rng
        self.velocity_ = np.zeros(2)
        self.last_centre_ = np.asarray(centre, float).copy()

    def _cov(self, states: np.ndarray, weights: np.ndarray) -> np.ndarray:
        return weighted_mean_cov(states, weights)[1] + np.eye(2) * 1e-6

    def predict(self) -> Estimate:
        # x_{i,t+1} = F(x_{i,t}) = x_{i,t} + v (v = 0: the paper's identity F);
        # the prediction is the weighted mean of the moved actions.
        self.core_.states_ = self.core_.states_ + self.velocity_
        centre = self._keep_in_frame(self.core_.predict())
        self.estimate_ = Estimate(self._box(centre), self._cov(self.core_.states_, self.core_.weights_),
                                  self.estimate_.confidence, self.estimate_.status)
        return self.estimate_

    def loss_map(self, smap: ScoreMap) -> ScoreMap:
        """The map of ``q(s)`` averaged over a square of half-side ``window`` box sizes.

        The paper's loss sums the clipped measurements over the object's
        extent; here the clipped score map is box-filtered over a window of
        ``2 window`` box sizes, which widens the needle-like NCC peak of a
        textured target into a basin the re-sampled actions can find.
        """
        q = np.clip(np.asarray(smap.scores, dtype=np.float32), self.clip[0], self.clip[1])
        k = 2 * int(round(self.window * self.scale_ / smap.step)) + 1
        if k > 1:
            q = cv2.blur(q, (k, k), borderType=cv2.BORDER_REPLICATE)
        return dataclasses.replace(smap, scores=q, stages={})

    def losses(self, qmap: ScoreMap, states: np.ndarray) -> np.ndarray:
        """``l_o(x_i) = -q(x_i)`` for action centres ``(N, 2)`` on a :meth:`loss_map`."""
        outside = float(np.clip(self.outside_score, self.clip[0], self.clip[1]))
        return -score_at_centres(qmap, states, outside)

    def _update(self, measurement: Measurement | None) -> Estimate:
        prior = self.estimate_
        quality = 0.0 if measurement is None else float(getattr(measurement, "quality", 0.0))
        if not _usable(measurement, self.lost_below):
            self.velocity_ = self.velocity_ * self.coast_damping   # coast to a stop, do not fly off
            self.stages_ = {"particles": np.column_stack([self.core_.states_, self.core_.weights_])}
            return self._lost(prior, quality, {"c_t": self.core_.c, "live_actions": float(self.core_.live_actions)})
        qmap = self.loss_map(measurement)
        centre = self.core_.step(lambda s: self.losses(qmap, s))
        centre = self._keep_in_frame(centre)
        if self.velocity_gain > 0:
            self.velocity_ = ((1 - self.velocity_gain) * self.velocity_
                              + self.velocity_gain * (centre - self.last_centre_))
        self.last_centre_ = centre.copy()
        states, weights = self.core_.current_states_, self.core_.weights_
        concentration = weight_concentration(states, weights, centre, self.radius * self.scale_)
        scalars = {"c_t": self.core_.c, "live_actions": float(self.core_.live_actions),
                   "concentration": concentration, "deleted": float(self.core_.deleted_)}
        self.stages_ = {"particles": np.column_stack([states, weights])}
        confidence = concentration * float(np.clip(quality, 0.0, 1.0))
        self.estimate_ = Estimate(self._box(centre), self._cov(states, weights), confidence, TRACKING, scalars,
                                  stages=self.stages_)
        return self.estimate_


def score_log_likelihood(scores: np.ndarray, sigma_s: float) -> np.ndarray:
    """``log p(s | x) = -(1 - s)^2 / (2 sigma_s^2)``: the box's score is 1 plus Gaussian noise."""
    return -np.square(1.0 - scores) / (2.0 * sigma_s ** 2)


class ParticleBoxFilter(_CentreBoxFilter):
    """SIR particle filter over box centres on a score map; see the module docstring.

    Parameters
    ----------
    n_particles
    sigma_d
        Random-walk standard deviation per frame, in box sizes.
    sigma_s
        Score noise of the likelihood.
    outside_score, lost_below, radius, rng, confidence, reseed_above
        As in :class:`NormalHedgeBoxFilter`.
    """

    def __init__(self, n_particles: int = 100, sigma_d: float = 0.2, sigma_s: float = 0.1,
                 outside_score: float = 0.0, lost_below: float = 0.35, radius: float = 0.15,
                 rng: np.random.Generator | int | None = None, confidence: str | None = None,
                 reseed_above: float | None = None) -> None:
        self.confidence = confidence
        self.reseed_above = reseed_above
        self.n_particles = n_particles
        self.sigma_d = sigma_d
        self.sigma_s = sigma_s
        self.outside_score = outside_score
        self.lost_below = lost_below
        self.radius = radius
        self.rng = rng

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self._start(box, frame)
        step = self.sigma_d * self.scale_

        def propagate(x, rng):  # x_k = x_{k-1} + N(0, sigma_d^2 I)
            return x + step * rng.standard_normal(x.shape)

        def log_likelihood(x, smap):
            return score_log_likelihood(score_at_centres(smap, x, self.outside_score), self.sigma_s)

        self.core_ = ParticleFilter(propagate, log_likelihood, self.rng)
        self.core_.initialize(np.tile(box.center, (self.n_particles, 1)))
        self.estimate_ = Estimate(box, np.eye(2) * step ** 2, 1.0, TRACKING)
        self.stages_ = {}

    def _reseed(self, centre: np.ndarray) -> None:
        """Restart every particle at ``centre`` (the random stream continues)."""
        rng = self.core_.rng_
        self.core_.initialize(np.tile(centre, (self.n_particles, 1)))
        self.core_.rng_ = rng

    def predict(self) -> Estimate:
        # The SIR step propagates and weights together; the prior's mean is the
        # current mean (the random walk does not move it).
        mean, cov = weighted_mean_cov(self.core_.particles_, self.core_.weights_)
        step = self.sigma_d * self.scale_
        self.estimate_ = Estimate(self._box(self._keep_in_frame(mean)), cov + np.eye(2) * step ** 2,
                                  self.estimate_.confidence, self.estimate_.status)
        return self.estimate_

    def _update(self, measurement: Measurement | None) -> Estimate:
        prior = self.estimate_
        quality = 0.0 if measurement is None else float(getattr(measurement, "quality", 0.0))
        if not _usable(measurement, self.lost_below):
            self.core_.step(None)  # predict only: the cloud spreads by the random walk
            self.stages_ = {"particles": np.column_stack([self.core_.particles_, self.core_.weights_])}
            return self._lost(prior, quality, {})
        log_evidence = self.core_.step(measurement)
        mean, cov = weighted_mean_cov(self.core_.particles_, self.core_.weights_)
        mean = self._keep_in_frame(mean)
        concentration = weight_concentration(self.core_.particles_, self.core_.weights_, mean,
                                             self.radius * self.scale_)
        self.stages_ = {"particles": np.column_stack([self.core_.particles_, self.core_.weights_])}
        scalars = {"concentration": concentration, "log_evidence": float(log_evidence),
                   "effective_particles": float(1.0 / np.sum(self.core_.weights_ ** 2))}
        confidence = concentration * float(np.clip(quality, 0.0, 1.0))
        self.estimate_ = Estimate(self._box(mean), cov, confidence, TRACKING, scalars, stages=self.stages_)
        return self.estimate_


class GridBayesBoxFilter(_CentreBoxFilter):
    """Exact grid Bayes filter over box centres on a grid that moves with the estimate; see the module docstring.

    The grid is a window of the lattice ``spacing * (i, j)`` (anchored at the
    frame origin) reaching ``extent`` box sizes on each side of the estimate.
    Before each prediction it is re-centred on the posterior mean by whole
    cells (the probability of cells that leave the window is dropped, then
    the rest renormalised), so the filter's cost depends on the box, not on the
    frame: a 640x480 frame costs what a 320x240 one does.  Within the window
    the recursion is exact.

    Parameters
    ----------
    cell
        Grid spacing in box sizes (at least ``min_spacing`` pixels).
    min_spacing
        Smallest grid spacing, pixels (bounds the cost on small boxes).
    extent
        Half-width of the grid window, in box sizes (the detector's window reaches about 1.75).
    sigma_d, sigma_s, outside_score, lost_below, radius, confidence, reseed_above
        As in :class:`ParticleBoxFilter`.
    """

    def __init__(self, cell: float = 0.1, sigma_d: float = 0.1, sigma_s: float = 0.1,
                 outside_score: float = 0.0, lost_below: float = 0.35, radius: float = 0.15,
                 min_spacing: float = 2.0, extent: float = 2.0, rng: np.random.Generator | int | None = None,
                 confidence: str | None = None, reseed_above: float | None = None) -> None:
        self.confidence = confidence
        self.reseed_above = reseed_above
        self.cell = cell
        self.min_spacing = min_spacing
        self.extent = extent
        self.sigma_d = sigma_d
        self.sigma_s = sigma_s
        self.outside_score = outside_score
        self.lost_below = lost_below
        self.radius = radius
        self.rng = rng

    def _place(self, corner: tuple[int, int]) -> None:
        """Put the grid window's first cell at lattice index ``corner = (row, col)``."""
        self.corner_ = corner
        self.ys_ = (corner[0] + np.arange(self.shape_[0])) * self.spacing_
        self.xs_ = (corner[1] + np.arange(self.shape_[1])) * self.spacing_
        self.gx_, self.gy_ = np.meshgrid(self.xs_, self.ys_)
        self.centres_ = np.column_stack([self.gx_.ravel(), self.gy_.ravel()])

    def _corner_at(self, centre: np.ndarray) -> tuple[int, int]:
        return (int(round(centre[1] / self.spacing_)) - self.shape_[0] // 2,
                int(round(centre[0] / self.spacing_)) - self.shape_[1] // 2)

    def initialize(self, box: Box, frame: Frame | None = None) -> None:
        self._start(box, frame)
        self.spacing_ = max(self.min_spacing, self.cell * self.scale_)
        half = np.ceil(self.extent * box.size / self.spacing_).astype(int)
        self.shape_ = (2 * int(half[1]) + 1, 2 * int(half[0]) + 1)            # rows, cols
        self._place(self._corner_at(box.center))
        sigma = max(self.sigma_d * self.scale_, 0.5 * self.spacing_)
        self.transitions_ = [gaussian_transition(self.ys_ - self.ys_[0], sigma),
                             gaussian_transition(self.xs_ - self.xs_[0], sigma)]   # translation-invariant
        p = np.zeros(self.shape_)
        p[self.shape_[0] // 2, self.shape_[1] // 2] = 1.0                     # prior: the init box
        self.p_ = grid_predict_separable(p, self.transitions_)
        self.estimate_ = Estimate(box, np.eye(2) * sigma ** 2, 1.0, TRACKING)
        self.stages_ = {}

    def _reseed(self, centre: np.ndarray) -> None:
        """Restart the grid on ``centre``: all the probability in its cell, spread by one random-walk step."""
        self._place(self._corner_at(centre))
        p = np.zeros(self.shape_)
        p[self.shape_[0] // 2, self.shape_[1] // 2] = 1.0
        self.p_ = grid_predict_separable(p, self.transitions_)

    def _recentre(self) -> None:
        """Move the window by whole cells so the posterior mean is at its centre (mass outside dropped)."""
        mean, _ = self._moments()
        corner = self._corner_at(mean)
        dr, dc = corner[0] - self.corner_[0], corner[1] - self.corner_[1]
        if dr == 0 and dc == 0:
            return
        h, w = self.shape_
        moved = np.zeros_like(self.p_)
        src = self.p_[max(dr, 0):h + min(dr, 0), max(dc, 0):w + min(dc, 0)]
        moved[max(-dr, 0):max(-dr, 0) + src.shape[0], max(-dc, 0):max(-dc, 0) + src.shape[1]] = src
        total = moved.sum()
        self.p_ = moved / total if total > 0 else np.full_like(moved, 1.0 / moved.size)
        self._place(corner)

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        px, py = self.p_.sum(axis=0), self.p_.sum(axis=1)
        mean = np.array([px @ self.xs_, py @ self.ys_])
        var = np.array([px @ (self.xs_ - mean[0]) ** 2, py @ (self.ys_ - mean[1]) ** 2])
        return mean, np.diag(var)

    def _points(self, limit: int = 400) -> np.ndarray:
        """The most probable cells as ``(K, 3)`` ``[cx, cy, p]``."""
        flat = self.p_.ravel()
        k = min(limit, flat.size)
        top = np.argpartition(flat, -k)[-k:]
        rows, cols = np.unravel_index(top, self.p_.shape)
        return np.column_stack([self.xs_[cols], self.ys_[rows], flat[top]])

    def predict(self) -> Estimate:
        self._recentre()
        self.p_ = grid_predict_separable(self.p_, self.transitions_)   # p(x_k | z_1:k-1)
        mean, cov = self._moments()
        self.estimate_ = Estimate(self._box(mean), cov, self.estimate_.confidence, self.estimate_.status)
        return self.estimate_

    def _update(self, measurement: Measurement | None) -> Estimate:
        prior = self.estimate_
        quality = 0.0 if measurement is None else float(getattr(measurement, "quality", 0.0))
        if not _usable(measurement, self.lost_below):
            self.stages_ = {"particles": self._points()}
            return self._lost(prior, quality, {})
        scores = score_at_centres(measurement, self.centres_, self.outside_score)
        loglik = score_log_likelihood(scores, self.sigma_s).reshape(self.p_.shape)
        self.p_ = grid_update_log(self.p_.ravel(), loglik.ravel()).reshape(self.p_.shape)
        mean, cov = self._moments()
        d2 = (self.gx_ - mean[0]) ** 2 + (self.gy_ - mean[1]) ** 2
        concentration = float(self.p_[d2 <= (self.radius * self.scale_) ** 2].sum())
        self.stages_ = {"particles": self._points()}
        confidence = concentration * float(np.clip(quality, 0.0, 1.0))
        self.estimate_ = Estimate(self._box(mean), cov, confidence, TRACKING, {"concentration": concentration},
                                  stages=self.stages_)
        return self.estimate_
