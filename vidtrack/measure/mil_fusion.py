"""``mil``'s measurer: Wnuk & Soatto's superpixel inliers fused with a correlation filter.

:class:`MILMeasurer` runs the paper's appearance side
(:class:`~vidtrack.measure.mil.MILAppearance`: superpixels, Pegasos SVM,
graph-cut inliers) and, beside it, a discriminative correlation filter on
HOG and Lab cells (:class:`~vidtrack.measure.correlation.CorrelationFilter`:
BACF's constraint, Staple's colour merge, DSST's scale filter), learned from
the posterior box of confident frames.  What the filter adds, each part of
:class:`FusionConfig`:

* centre (``refine``): the filter is evaluated on a window around the
  prediction; the measured centre is where its response (divided by its
  peak) less ``motion`` times the squared distance from the inlier-based
  centre (box units) peaks (:func:`fuse_peak`), so superpixel evidence and
  the filter vote together.  Below ``min_quality`` the inlier centre is
  kept, and the measurement's quality is scaled by ``quality / min_quality``
  in any case;
* scale (``size_from="cf"``): the size is the scale filter's estimate at the
  detected centre; the Kalman filter smooths it, the size rate decaying
  every frame (:class:`~vidtrack.filters.mil.MILKalmanFilter`).  The
  paper's own size measurement, the inlier extent, shrinks the box when the
  inliers cover only part of the object;
* failure and recovery (``redetect``): while lost, the correlation window
  stays on the prediction; after ``global_after`` lost frames (a loss that
  long is no longer an occlusion), every ``global_every`` frames, the
  filter restricted to the target's own cells (so a static background the
  target left does not fire) is slid over the whole frame and the window is
  searched around its best peak (in a frame more than ``global_boxes`` box
  sizes across, the region of that many box sizes around the prediction:
  the search's memory and time follow the box).  A peak of quality at least ``reacquire``
  away from the prediction is only a proposal: the superpixels, the SVM and
  the graph cut run around it, and it becomes the measurement only if they
  find the target's inliers there.  Searching the whole frame from the
  first lost frame would let a look-alike take over while the target is
  occluded;
* a target that outruns the bag (``recentre``): the positive bag and the
  cut's spatial prior sit on the prediction, so a target that moved faster
  than the Kalman filter expects leaves them and the inliers measure
  nothing, while the correlation window, several boxes wide, still sees it.
  When the inliers give no measurement and the filter's peak, of quality at
  least ``recentre``, lies more than a tenth of a box from the prediction,
  the superpixels, the SVM and the graph cut run again around that peak;
  what they find there is the measurement.  As in re-detection the filter
  only proposes: a peak on an occluder or on clutter finds no inliers and
  the frame stays unmeasured;
* lost or present (``present``): a frame with no usable measurement is
  still reported ``tracking`` (predicted only) when the filter's quality
  reaches ``present`` and its peak lies within half a box of the
  prediction (the prediction itself, also when a second search ran around
  the peak and found nothing there), so ``lost`` means that neither cue
  sees the target.  It changes the reported status, and a box only through
  the search of a frame reported lost (``search_when_lost``; with the
  calibrated confidence the status is the presence model's, of which
  ``present`` is one cue).

Speed, without changing a result: the filter's update from the last frame
and its detection in this one run on a second thread
(:class:`~vidtrack.measure.threads.SecondThread`) while this one computes
the superpixels, the SVM scores, the graph cut and the inlier box; only the
fusion (and the re-detection it may start) waits for the filter.  When the second thread is still learning as a
frame arrives, this one also cuts the filter's search window (which does
not depend on what the filter learns).  The per-pixel loops (SLIC,
the descriptors, the inliers' peak, HOG, the colour model, Pegasos) are
compiled with Numba and release the GIL, so both threads really run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ..config import option
from ..types import LOST, Box, Estimate, Frame, Superpixels
from .correlation import CorrelationConfig, CorrelationFilter, CorrelationResult
from .mil import GraphCutConfig, InlierBox, InlierSearch, MILAppearance, SuperpixelConfig, SVMConfig
from .threads import SecondThread, tic


def global_region(frame_size: np.ndarray, centre, box_size, max_boxes: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre and size of the re-detection region: the whole frame, at most ``max_boxes`` box sizes per side.

    Along an axis where the frame is wider than ``max_boxes`` box sizes the
    region is that wide, around ``centre`` and shifted to lie inside the
    frame; elsewhere it is the frame.
    """
    frame_size = np.asarray(frame_size, float)
    region = np.minimum(frame_size, max_boxes * np.maximum(np.asarray(box_size, float), 1.0))
    low = np.clip(np.asarray(centre, float) - region / 2.0, 0.0, frame_size - region)
    return low + region / 2.0, region


@dataclass(frozen=True)
class FusionConfig:
    """How the correlation filter joins the superpixels: centre, size, re-detection and the lost status.

    The filter runs when it moves the centre (``refine``) or gives the size
    (``size_from="cf"``); without it ``redetect`` and ``present`` do nothing.
    """

    refine: bool = option(True, "move the inlier centre to the fused peak of the correlation response")
    size_from: Literal["cf", "inliers", "none"] = option(
        "cf", "the measured size: cf (the scale filter), inliers (their extent, the paper's h_2) or none "
              "(the prediction's)")
    min_quality: float = option(0.15, "correlation quality from which its peak and scale are used; below it "
                                      "the measurement's quality is scaled by quality / min_quality")
    motion: float = option(0.05, "weight of the squared distance (box units) from the inlier centre "
                                 "in the fused peak")
    learn_above: float = option(0.2, "the filter learns only from frames whose detection reached this quality")
    redetect: bool = option(True, "while lost, correlation peaks propose where the superpixels search")
    reacquire: float = option(0.9, "quality of a peak away from the prediction that moves the superpixel search "
                                   "there")
    global_after: int = option(30, "lost frames before the whole frame is searched")
    global_every: int = option(5, "then the whole frame is searched every this many frames")
    global_boxes: float = option(32.0, "the whole-frame search covers at most this many box sizes per side, "
                                       "around the prediction, so its cost follows the box, not the frame")
    present: float | None = option(0.5, "a predicted-only frame is still tracking when the filter's peak of this "
                                        "quality lies within half a box of the prediction (none: it is lost)")
    search_when_lost: bool = option(True, "a frame the filter reports lost (its calibrated lost rule) is "
                                           "searched as an unmeasured one: wider bag, re-detection")
    recentre: float | None = option(0.5, "a frame whose inliers give no measurement is searched again around the "
                                         "filter's peak when its quality reaches this (none: never)")
    core: bool = option(True, "run the paper's superpixel / SVM / graph-cut core (off: the correlation filter "
                              "alone measures the box, an ablation)")

    @property
    def uses_correlation(self) -> bool:
        """Whether the correlation filter runs at all."""
        return self.refine or self.size_from == "cf" or not self.core


@dataclass(frozen=True)
class MILMeasurerConfig:
    """The configuration of :class:`MILMeasurer`: the paper's three parts, the correlation filter, the fusion."""

    superpixels: SuperpixelConfig = option(SuperpixelConfig(), "search region, SLIC superpixels, descriptors")
    svm: SVMConfig = option(SVMConfig(), "the Pegasos SVM and its training set")
    graphcut: GraphCutConfig = option(GraphCutConfig(), "positive bag, graph cut, inlier measurement")
    correlation: CorrelationConfig = option(CorrelationConfig(), "the correlation filter (HOG and Lab cells, "
                                                                 "BACF, Staple's colour, DSST's scale)")
    fusion: FusionConfig = option(FusionConfig(), "the correlation filter with the superpixels: centre, size, "
                                                  "re-detection, lost")


def _peak_offset(cf: CorrelationResult | None, prior: Estimate) -> float:
    """The distance from the prediction to the filter's peak in box sizes (``sqrt(w h)``); infinite without a peak."""
    if cf is None:
        return np.inf
    return float(np.linalg.norm(cf.centre - prior.box.center) / max(prior.box.scale, 1e-6))


def fuse_peak(result: CorrelationResult, anchor: np.ndarray, weight: float, unit: float) -> np.ndarray:
    """Where the response, less ``weight`` times the squared distance from ``anchor`` in ``unit``s, peaks.

    The fusion of :class:`MILMeasurer`: the correlation response (divided by
    its peak) is traded against the distance from the superpixel inliers'
    centre; the maximum is refined to sub-cell by parabolas.  Returns the
    frame position ``(x, y)``.
    """
    h, w = result.response.shape
    xs = result.window_centre[0] + (np.arange(w) - w // 2) * result.step
    ys = result.window_centre[1] + (np.arange(h) - h // 2) * result.step
    d2 = ((ys[:, None] - anchor[1]) ** 2 + (xs[None, :] - anchor[0]) ** 2) / max(unit, 1e-6) ** 2
    objective = result.response / max(result.peak, 1e-9) - weight * d2
    r, c = np.unravel_index(int(np.argmax(objective)), objective.shape)

    def offset(a: float, b: float, cc: float) -> float:
        den = a - 2.0 * b + cc
        return float(np.clip(0.5 * (a - cc) / den, -0.5, 0.5)) if den < 0 else 0.0

    dr = offset(objective[r - 1, c], objective[r, c], objective[r + 1, c]) if 0 < r < h - 1 else 0.0
    dc = offset(objective[r, c - 1], objective[r, c], objective[r, c + 1]) if 0 < c < w - 1 else 0.0
    return np.array([xs[c] + dc * result.step, ys[r] + dr * result.step])


class MILMeasurer:
    """Superpixels + Pegasos SVM + graph-cut inliers, fused with a correlation filter (``mil``'s measurer).

    Parameters
    ----------
    config
        A :class:`MILMeasurerConfig` (``mil``'s recipe passes its whole
        :class:`~vidtrack.recipes.mil.MILConfig`).
    rng
        Generator, seed or None for Pegasos' mini-batches.
    threads
        Run the correlation filter on a second thread beside the superpixels
        (False: one thread).  The results are the same either way; only the
        wall clock differs.

    Attributes
    ----------
    timings_, cf_timings_
        Seconds per stage since :meth:`initialize` (profiling, read by
        ``vidtrack bench``): this thread's stages, and the correlation
        filter's when it runs on the second thread (overlapping the others).
    """

    def __init__(self, config: MILMeasurerConfig = MILMeasurerConfig(), *,
                 rng: np.random.Generator | int | None = None, threads: bool = True) -> None:
        self.config = config
        self.rng = rng
        self.threads = threads

    def __getstate__(self) -> dict:
        # the worker thread does not pickle (process pools, deepcopy): finish its tasks, then leave it out
        if getattr(self, "tasks_", None):
            self._wait_correlation()
        return dict(self.__dict__)

    # -- Measurer protocol -----------------------------------------------

    def initialize(self, frame: Frame, box: Box) -> None:
        """Bootstrap the SVM from the first frame's superpixels and learn the correlation filter from ``box``."""
        c = self.config
        if getattr(self, "worker_", None) is not None:
            self.worker_.close()   # a previous run's tasks finish first
        self.worker_ = SecondThread(self.threads, "vidtrack-mil")
        self.tasks_: list = []
        self.timings_: dict[str, float] = {}
        self.cf_timings_: dict[str, float] = {}
        self.last_ = None
        self.cf_ = None
        self.cf_result_: CorrelationResult | None = None
        self.lost_run_ = 0
        self.coasting_ = False
        if c.fusion.uses_correlation:
            t0 = time.perf_counter()
            self.cf_ = CorrelationFilter(c.correlation)
            self.cf_.initialize(frame.image, box)
            self._background_tic("correlation", t0)
        self.appearance_ = None
        if c.fusion.core:
            self.appearance_ = MILAppearance(c.superpixels, c.svm, c.graphcut, rng=self.rng)
            self.appearance_.initialize(frame, box, timings=self.timings_)

    def measure(self, frame: Frame, prior: Estimate) -> Superpixels | None:
        """Superpixels of the search region, SVM scores, graph-cut inliers, and the box fused with the filter's."""
        f = self.config.fusion
        self.last_ = None
        sigma = np.zeros(2)
        if prior.covariance is not None:
            sigma = np.sqrt(np.maximum(np.diag(prior.covariance)[:2], 0.0))
        searching = self._searching(prior)
        self.lost_run_ = self.lost_run_ + 1 if searching else 0
        whole_frame = (searching and f.redetect and self.lost_run_ >= f.global_after
                       and self.lost_run_ % max(f.global_every, 1) == 0)
        # the correlation filter (on the second thread) and the superpixel side run side by side; while the
        # second thread is still learning from the last frame, the filter's window is cut here
        if self.cf_ is not None:
            window = None
            if not whole_frame and any(not task.done() for task in self.tasks_):
                t0 = time.perf_counter()
                window = self.cf_.window(frame.image, prior.box.center, prior.box.size)
                tic(self.timings_, "correlation window", t0)
            self.tasks_.append(self.worker_.submit(self._correlate, frame, prior, whole_frame, window))
        if self.appearance_ is None:
            return self._correlation_alone(prior)
        found = self.appearance_.search(frame, prior, sigma, searching=searching)
        inlier, stages = self._inlier_stages(found)   # all that does not need the filter, before waiting for it
        cf = self._wait_correlation()
        self.cf_result_ = cf
        offset = _peak_offset(cf, prior)
        redetect = cf is not None and f.redetect and searching and cf.quality >= f.reacquire and offset > 0.5
        recentre = (cf is not None and f.recentre is not None and found is not None and inlier is None
                    and cf.quality >= f.recentre and offset > 0.1)
        if redetect or recentre:
            # the correlation filter proposes, the superpixels and the SVM verify there (the prior itself stays:
            # presence below is judged against the prediction, not against the peak searched)
            at_peak = replace(prior, box=Box.from_center(*cf.centre, *prior.box.size))
            found = self.appearance_.search(frame, at_peak, sigma, searching=searching)
            inlier, stages = self._inlier_stages(found)
        if found is None:
            return None
        box, quality = (None, 0.0) if inlier is None else self._fuse(inlier, cf, prior)
        self.last_ = found
        labels, scores, inliers = found.labels, found.scores, found.inliers
        if cf is not None:
            stages["correlation"] = cf.response.astype(np.float32)
            stages["psr"] = float(cf.psr)
        if inlier is not None:
            stages["inlier_coverage"] = inlier.coverage
            if cf is not None:   # do the two cues agree on where the target is? (box units)
                gap = np.linalg.norm(cf.centre - np.asarray(inlier.centre)) / max(prior.box.scale, 1e-6)
                stages["cue_agreement"] = float(gap)
        present = self._present(cf, offset)
        return Superpixels(labels=labels, features=found.features, scores=scores, inliers=inliers, box=box,
                           quality=quality, search_region=found.region.box, stages=stages, present=bool(present))

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        """The correlation filter and the SVM learn from a confident frame's posterior box.

        The filter's update is queued first (on the second thread, with the
        next frame's detection it is the longer path); then the superpixels
        are relabelled (:meth:`~vidtrack.measure.mil.MILAppearance.learn`).
        Nothing is learned while lost.
        """
        self.coasting_ = posterior.scalars.get("measured", 1.0) == 0.0
        data = self.last_
        if self.appearance_ is None:
            confident = (not self.coasting_ and posterior.scalars.get("quality", posterior.confidence)
                         >= self.config.svm.learn_above)
        else:
            confident = data is not None and self.appearance_.confident(posterior)
        cf = self.cf_result_
        if confident and cf is not None and cf.quality >= self.config.fusion.learn_above:
            self.tasks_.append(self.worker_.submit(self._update_correlation, frame.image, posterior.box))
        if self.appearance_ is not None:
            self.appearance_.learn(data if confident else None, posterior.box)

    # -- helpers --------------------------------------------------------

    def _correlation_alone(self, prior: Estimate) -> Superpixels | None:
        """The measurement without the superpixel core: the correlation peak and scale, of the filter's quality.

        Re-detection has nothing to verify a distant peak with: a peak of
        quality ``reacquire`` found by the whole-frame search is taken as it is.
        """
        f = self.config.fusion
        cf = self._wait_correlation()
        self.cf_result_ = cf
        if cf is None:
            return None
        size = cf.size if f.size_from == "cf" else prior.box.size
        box = Box.from_center(float(cf.centre[0]), float(cf.centre[1]), float(size[0]), float(size[1]))
        empty = np.zeros(0)
        present = self._present(cf, _peak_offset(cf, prior))
        return Superpixels(labels=np.zeros((0, 0), np.int32), features=np.zeros((0, 0)), scores=empty,
                           inliers=empty.astype(bool), box=box, quality=float(cf.quality),
                           stages={"correlation": cf.response.astype(np.float32), "psr": float(cf.psr)},
                           present=bool(present))

    def _inlier_stages(self, found: InlierSearch | None) -> tuple[InlierBox | None, dict]:
        """The inlier box of a superpixel search and its per-pixel stages (superpixels, SVM scores, inliers)."""
        if found is None:
            return None, {}
        labels = found.labels
        return self.appearance_.inlier_box(found), {
            "superpixels": labels,
            "svm_scores": found.scores[labels].astype(np.float32),
            "inliers": found.inliers[labels].astype(np.uint8),
        }

    def _fuse(self, inlier: InlierBox, cf: CorrelationResult | None, prior: Estimate) -> tuple[Box, float]:
        """The measured box and its quality: the inlier centre moved by the correlation peak, the size from ``size_from``."""
        f = self.config.fusion
        fx, fy = inlier.centre
        quality = inlier.quality
        size = inlier.size if f.size_from == "inliers" else prior.box.size
        if cf is not None:
            if f.refine and cf.quality >= f.min_quality:
                fx, fy = fuse_peak(cf, np.array([fx, fy]), f.motion, prior.box.scale)
            quality *= float(np.clip(cf.quality / max(f.min_quality, 1e-6), 0.0, 1.0))
            if f.size_from == "cf" and cf.quality >= f.min_quality:
                size = cf.size
        return Box.from_center(float(fx), float(fy), float(size[0]), float(size[1])), quality

    def _present(self, cf: CorrelationResult | None, offset: float) -> bool:
        """``fusion.present``: a filter peak of that quality, ``offset <= 0.5`` box sizes from the prediction."""
        f = self.config.fusion
        return cf is not None and f.present is not None and cf.quality >= f.present and offset <= 0.5

    def _searching(self, prior: Estimate) -> bool:
        """Search as when lost: the last frame was only predicted, or (``search_when_lost``) reported lost."""
        return self.coasting_ or (self.config.fusion.search_when_lost and prior.status == LOST)

    def _wait_correlation(self) -> CorrelationResult | None:
        """Wait for the queued correlation tasks in order (re-raising the first error); the last one's result."""
        tasks, self.tasks_ = self.tasks_, []
        if not tasks:
            return None
        t0 = time.perf_counter()
        result = None
        try:
            for task in tasks:
                result = task.result()
        finally:
            tic(self.timings_, "correlation (wait)", t0)
        return result

    def _background_tic(self, name: str, start: float) -> None:
        """Time a correlation task: in ``cf_timings_`` when it runs on the second thread, else in ``timings_``."""
        tic(self.cf_timings_ if self.threads else self.timings_, name, start)

    def _update_correlation(self, image: np.ndarray, box: Box) -> None:
        t0 = time.perf_counter()
        self.cf_.update(image, box)
        self._background_tic("correlation", t0)

    def _correlate(self, frame: Frame, prior: Estimate, whole_frame: bool, window: tuple | None = None
                   ) -> CorrelationResult:
        """The correlation filter's detection around the prior; with ``whole_frame``, around the frame's best peak.

        ``measure`` asks for the whole frame after ``global_after`` lost
        frames, every ``global_every`` frames: the target-only filter is slid
        over the whole frame and the window is searched around its best peak.
        Before that a loss is taken for an occlusion: only the window around
        the prediction is searched.  Runs on the second thread: it reads only
        its arguments and the filter.  ``window``: the filter's
        :meth:`~vidtrack.measure.correlation.CorrelationFilter.window` around
        the prior, already cut.
        """
        t0 = time.perf_counter()
        size = prior.box.size
        centre = prior.box.center
        if whole_frame:
            centre_, region = global_region(np.array([frame.width, frame.height], float), centre, size,
                                            self.config.fusion.global_boxes)
            centre = self.cf_.search(frame.image, centre_, region, size).centre   # target only: no stale context
        result = self.cf_.detect(frame.image, centre, size, window=window)
        self._background_tic("correlation", t0)
        return result
