"""Multiple Instance Filtering (Wnuk & Soatto): the measurement side (superpixels, SVM, graph cut).

Model (sec. 1.2, eqs. 2 and 8 of the paper)::

    x(t+1) = F x(t) + v(t),          x = [c, v_c, d, v_d]   (centre, its velocity, size, its rate)
    w(t+1) = stochSubgradIters(w(t), y(t), O(t))          (Pegasos, vidtrack.learn.pegasos)
    O(t)   = argmin_O E(y(t), w(t), x(t), O)             (graph cut, vidtrack.learn.graphcut)
    h(y(t)_{i in O(t)}) = C x(t) + n(t)                  (centroid and extent of the inliers)

The state, ``F``, ``C`` and the Kalman filter are in
:mod:`vidtrack.filters.mil`; this module is the appearance side.

Two pieces sit on the tracker's data path:

* :class:`MILMeasurer` cuts the search region (the prediction enlarged by
  ``lam = 3`` standard deviations of the predicted centre, eq. 8), computes
  SLIC superpixels there, their descriptors and chi-squared feature maps,
  the SVM scores, and the inliers by a graph cut inside the positive bag;
  the measurement is the centroid and extent of the inlier pixels.  In
  ``learn`` it relabels the frame's superpixels from the filter's posterior
  (the semi-supervised loop of eq. 5) into a training set of
  ``(descriptor, label, time)`` triples kept ``gamma_max = 25`` frames, and
  takes Pegasos steps every ``update_every = 6`` frames.
* :class:`MILKalmanFilter` is the Kalman filter on ``x``; no inliers means
  predict only and status ``lost``.

Where the paper is unclear (or garbled in the extracted text), this module assumes:

* search region: half-extent ``d/2 + pad d + min(3 sigma, max_extra d)`` per
  axis, ``sigma = sqrt diag(C P C')`` of the centre (eq. 8 keeps only "factor 3");
  the region is resampled so the box spans about ``object_pixels`` pixels;
* Pegasos projects on the L2 ball of radius ``1/sqrt(lambda)`` (the Pegasos
  paper; the extracted text reads "||w||_1 <= 1"), with class-balanced hinge
  loss, a regularised bias feature, mini-batches and a capped step counter;
* the first frame's triples stay in the training set (``keep_initial``), the
  others for ``gamma_max`` frames; nothing is learned from frames whose
  posterior confidence is under ``learn_above``;
* the positive bag is the superpixels whose centroid lies in the predicted box
  (scaled by ``bag_scale``); the cut's unaries add a spatial prior on the
  distance from the predicted centre (E may depend on x, sec. 1.2);
* the measured centre comes from the smoothed inlier map (fig. 3's "smoothed
  score used to select the bounding box location"); the extent of a partial
  inlier set is not the object's size, so with ``size_from="inliers"`` (the
  paper's ``h_2``) the size is measured only when the inliers cover
  ``size_coverage`` of the box; on the benchmark sequences such a measured
  size shrank the box to half its height within 60 frames, which is why the
  default measures the size with the correlation filter's scale estimate.

Extensions beyond the seed (documented departures, each switchable; the
ablation in the README shows what each buys):

* correlation-filter refinement (``refine="cf"``, the default): a
  discriminative correlation filter on HOG and Lab cells
  (:class:`~vidtrack.measure.correlation.CorrelationFilter`, learned from the
  posterior box of confident frames) is evaluated on a window around the
  prediction; the measured centre is where its response (divided by its
  peak) less ``cf_motion`` times the squared distance from the inlier-based
  centre (box units) peaks (:func:`~vidtrack.measure.correlation.fuse_peak`),
  so superpixel evidence and the filter vote together.  Below ``cf_min``
  quality the inlier centre is kept and the measurement's quality is scaled
  down by ``quality / cf_min``;
* scale (``size_from="cf"``): the size is DSST's scale-filter estimate at the
  detected centre; the Kalman filter smooths it (``r_size``, ``q_size``)
  with the size rate decaying by ``size_damping`` per frame (see
  :class:`~vidtrack.filters.mil.MILKalmanFilter`);
* failure and recovery: while lost, the superpixel region and the positive
  bag grow with the covariance (eq. 8, ``lost_bag``) and the correlation
  window stays on the prediction; after ``global_after`` lost frames (a loss
  that long is no longer an occlusion), every ``global_every`` frames, the
  filter restricted to the target's own cells (so a static background the
  target left does not fire) is slid over the whole frame and the window is
  searched around its best peak.  A peak of quality at least
  ``cf_reacquire`` away from the prediction is only a proposal: the
  superpixels, the SVM and the graph cut run around it, and it becomes the
  measurement only if they find the target's inliers there.  Searching
  wide from the first lost frame made ``data/sample.mp4``'s look-alike take
  over while the target was behind the post;
* centre refinement by NCC (``refine="ncc"``, the previous default):
  normalised cross-correlation (:func:`match_templates`) of a grey template
  of the object within ``ncc_radius`` box sizes of the inlier centre; the
  template is the first frame's patch together with a running average
  (rate ``ncc_rate``) updated only from confident frames whose match reached
  ``ncc_min``; the two NCC maps are averaged (``ncc_combine``).  The match
  maximises the NCC minus ``ncc_motion`` times the squared displacement
  from the inlier-based centre (in box units).  A match below ``ncc_min``
  keeps the superpixel centre; the measurement's quality falls linearly to
  0 as the match falls from ``ncc_min`` to ``ncc_floor``; with no inliers
  the template is searched over the covariance-enlarged window and accepted
  above ``ncc_reacquire``;
* speed, without changing a result: the correlation filter's update and
  detection run on a second thread (``cf_thread``) while this one computes
  the superpixels, SVM scores and graph cut (and the Pegasos updates, or
  with ``svm_thread`` on the second thread); the per-pixel loops (SLIC, the
  superpixel descriptors and statistics, the inliers' peak and mean shift,
  the HOG histograms, the colour model, Pegasos' iterations) are compiled with Numba and release the GIL, so the two
  threads really run side by side (the compiled SLIC is the same algorithm
  as OpenCV's, not the same superpixels: ``slic="opencv"`` gives those); and
  (this one does change results, chosen on the tune split) the filter
  learns from its detection's window shifted in the Fourier domain
  (``cf_reuse_sample``) instead of a second, re-cut window;
* the measurement noise ``r_centre = 0.08`` (the refined centre is more
  precise than a superpixel centroid); while lost the velocities decay by
  ``coast_damping = 0.5`` per frame: a long coast on a velocity learned just
  before the loss carried the prediction away more often than it carried it
  through an occlusion;
* while lost, the positive bag and the graph cut's spatial prior are enlarged
  by ``lam sigma`` (``lost_bag``, the growth named under failure and
  recovery), so that inliers can be found wherever eq. 8's search region
  says the object may be.
"""

from __future__ import annotations

import time
from collections import defaultdict
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace

import cv2
import numba
import numpy as np

from ..learn.graphcut import select_inliers
from ..learn.pegasos import PegasosSVM
from ..types import LOST, TRACKING, Box, Estimate, Frame, Superpixels
from . import superpixels as sp
from .correlation import CorrelationFilter, CorrelationResult, fuse_peak
from .image import cut_patch, match_templates, to_gray

# ------------------------------------------------------------------ pure maths

def inlier_measurement(labels: np.ndarray, inliers: np.ndarray, *, weights: np.ndarray | None = None):
    """Centroid and extent of the inlier pixels (the paper's ``h_1``, ``h_2``), region pixels.

    The extent along each axis is ``sqrt(12 var)``, the side of a uniformly
    filled box with the same second moment (robust to a few stray pixels,
    unlike the bounding box of the inliers).

    Parameters
    ----------
    labels
        ``(h, w) int`` superpixel labels.
    inliers
        ``(K,) bool`` inlier superpixels.
    weights
        Optional ``(K,)`` non-negative weight per superpixel (default 1).

    Returns
    -------
    (centre ``(2,)``, size ``(2,)``, mass) or None when there is no inlier pixel.
    """
    w_sp = inliers.astype(float) if weights is None else inliers * np.asarray(weights, float)
    w_pix = w_sp[labels]
    mass = float(w_pix.sum())
    if mass <= 0:
        return None
    h, w = labels.shape
    vs, us = np.arange(h, dtype=float), np.arange(w, dtype=float)
    col = w_pix.sum(axis=0)
    row = w_pix.sum(axis=1)
    cu = float(col @ us) / mass
    cv = float(row @ vs) / mass
    var_u = float(col @ (us - cu) ** 2) / mass
    var_v = float(row @ (vs - cv) ** 2) / mass
    size = np.sqrt(12.0 * np.array([var_u, var_v]) + 1.0)
    return np.array([cu + 0.5, cv + 0.5]), size, mass


def locate_inliers(labels: np.ndarray, weights: np.ndarray, box_size: np.ndarray, start: np.ndarray, *,
                   iterations: int = 6):
    """Where the inliers concentrate: peak of the smoothed inlier map, refined by mean shift.

    The paper selects the box location on a smoothed score (its fig. 3).  The
    per-pixel inlier weight is blurred with a Gaussian of ``box_size / 4``;
    from its peak (ties broken towards ``start``) a few mean-shift steps with
    a flat box-sized window move to the centroid of the inlier pixels the box
    covers; the measurement is that centroid and the extent of those pixels.

    Parameters
    ----------
    labels
        ``(h, w) int`` superpixel labels.
    weights
        ``(K,)`` non-negative weight per superpixel (0 for outliers).
    box_size
        ``(2,)`` predicted box size ``(w, h)`` in region pixels.
    start
        ``(2,)`` predicted centre ``(u, v)`` in region pixels.

    Returns
    -------
    (centre ``(2,)``, size ``(2,)``, mass inside the box) or None when no weight.
    """
    w_pix = np.asarray(weights, float)[labels].astype(np.float32)
    if not np.any(w_pix > 0):
        return None
    sx, sy = max(box_size[0] / 4.0, 1.0), max(box_size[1] / 4.0, 1.0)
    smooth = cv2.GaussianBlur(w_pix, (0, 0), sigmaX=sx, sigmaY=sy)
    found, cu, cv, su, sv, mass = _peak_and_mean_shift(w_pix, smooth, float(start[0]), float(start[1]),
                                                       float(box_size[0]), float(box_size[1]), max(iterations, 1))
    if not found:
        return None
    return np.array([cu, cv]), np.array([su, sv]), mass


@numba.njit(cache=True, nogil=True)
def _peak_and_mean_shift(w_pix, smooth, start_u, start_v, box_w, box_h, iterations):
    """:func:`locate_inliers` after the blur: the prior-weighted peak, mean shift, the extent (compiled, no GIL).

    Returns ``(found, u, v, size_u, size_v, mass)``.
    """
    h, w = w_pix.shape
    best, v0, u0 = -np.inf, 0, 0
    for v in range(h):   # gentle preference for the prediction on ties: exp(-d^2 / 2) in box units
        dv = (v + 0.5 - start_v) / box_h
        prior_v = np.exp(-0.5 * dv * dv)
        for u in range(w):
            du = (u + 0.5 - start_u) / box_w
            value = smooth[v, u] * (prior_v * np.exp(-0.5 * du * du))
            if value > best:
                best, v0, u0 = value, v, u
    cu, cv = u0 + 0.5, v0 + 0.5
    x0 = y0 = x1 = y1 = 0
    mass = 0.0
    for _ in range(iterations):
        x0, y0 = int(np.round(cu - box_w / 2)), int(np.round(cv - box_h / 2))
        x1, y1 = int(np.round(cu + box_w / 2)), int(np.round(cv + box_h / 2))
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        mass = sum_u = sum_v = 0.0
        for y in range(y0, y1):
            for x in range(x0, x1):
                p = np.float64(w_pix[y, x])
                mass += p
                sum_u += p * (x + 0.5)
                sum_v += p * (y + 0.5)
        if mass <= 0:
            return False, 0.0, 0.0, 0.0, 0.0, 0.0
        nu, nv = sum_u / mass, sum_v / mass
        done = abs(nu - cu) <= 0.25 + 1e-5 * abs(cu) and abs(nv - cv) <= 0.25 + 1e-5 * abs(cv)   # np.allclose
        cu, cv = nu, nv
        if done:
            break
    sum_uu = sum_vv = 0.0   # the extent of the inliers in the last window, about the new centre
    for y in range(y0, y1):
        for x in range(x0, x1):
            p = np.float64(w_pix[y, x])
            sum_uu += p * (x + 0.5 - cu) ** 2
            sum_vv += p * (y + 0.5 - cv) ** 2
    return True, cu, cv, np.sqrt(12.0 * sum_uu / mass + 1.0), np.sqrt(12.0 * sum_vv / mass + 1.0), mass


# ------------------------------------------------------------------ the measurer


@dataclass
class _FrameData:
    """What ``measure`` computed, kept for ``learn``."""

    region: sp.Region
    labels: np.ndarray
    features: np.ndarray
    inliers: np.ndarray
    scores: np.ndarray
    grey: np.ndarray | None = None


class MILMeasurer:
    """Superpixels + Pegasos SVM + graph-cut inliers (the measurement side of MIL filtering).

    Parameters
    ----------
    lam
        Search region factor on the predicted centre's standard deviation (eq. 8; the paper fixes 3).
    pad
        Extra context around the predicted box, fraction of its size per side.
    max_extra
        Cap on ``lam * sigma`` as a fraction of the box size (bounds the region while lost).
    object_pixels
        The region is resampled so the box's ``sqrt(w h)`` spans about this many pixels (never upsampled).
    superpixels_per_side
        About this many superpixels across the box side.
    slic_iterations, slic_ruler
        SLIC k-means iterations and compactness.
    slic
        The SLIC implementation (:func:`~vidtrack.measure.superpixels.slic_labels`):
        ``"numba"`` (compiled, GIL-free) or ``"opencv"`` (``ximgproc``).
    positive_fraction
        Area fraction inside the box for a positive (paper: 0.7).
    negative_fraction
        At most this fraction inside the box for a negative when relabelling.
    gamma_max
        Frames a training triple is kept (paper: 25).
    update_every
        Pegasos update period in frames (paper: 6).
    svm_lam, svm_iter, svm_init_iter, svm_max_t, svm_batch
        Pegasos regularisation, iterations per update, at bootstrap, step-counter
        cap, and mini-batch size (None: the whole training set per step).
    keep_initial, anchor_weight
        Keep the first frame's triples in the training set for ever (an anchor
        against drift), counted ``anchor_weight`` times.
    bag_scale
        The positive bag: superpixels whose centroid is inside the predicted box scaled by this.
    cut_slope, cut_beta
        Graph cut: slope of the SVM-score sigmoid in the unaries, weight of the pairwise terms.
    feature_order
        Frequencies of the chi-squared feature map.
    min_inlier_fraction
        Inlier area below this fraction of the box area counts as no measurement.
    locate
        ``"smoothed"``: the box goes where the smoothed inlier map peaks
        (:func:`locate_inliers`); ``"centroid"``: centroid and extent of all
        inliers (:func:`inlier_measurement`).
    positive_margin
        A relabelled positive must also score above this (no self-training on
        superpixels the SVM does not already believe in).
    outliers_negative
        Label the cut's outliers inside the box negative when their score is negative (eq. 5).
    size_coverage
        The inlier extent measures the size only when the inliers cover at
        least this fraction of the predicted box; otherwise the measured size
        is the predicted one (no size information).
    learn_above
        Only frames whose posterior confidence reaches this add training triples.
    spatial_prior
        Extra cost of an inlier label growing with the squared normalised
        distance of the superpixel from the predicted centre (0: SVM scores only).
    lost_bag
        While the prior is ``lost``, enlarge the positive bag and the spatial
        prior's scale by ``lam sigma`` (capped by ``max_extra``) per side.
    refine
        ``"cf"``: fuse the inlier centre with the correlation filter's response
        (:func:`~vidtrack.measure.correlation.fuse_peak`); ``"ncc"``: refine
        it by template matching (:func:`match_templates`); ``"none"``: the
        inlier centre (the paper).  The first two are extensions beyond the paper.
    size_from
        Where the measured size comes from: ``"cf"`` the correlation filter's
        scale estimate, ``"inliers"`` the inlier extent (the paper's ``h_2``),
        ``"none"`` nowhere (the predicted size).
    cf_min
        Correlation quality (PSR-based, [0, 1]) from which its peak moves the
        centre and its scale sets the size; below it the measurement's quality
        is scaled by ``quality / cf_min``.
    cf_motion
        Weight of the squared distance (box units) from the inlier centre in the fusion.
    cf_reacquire
        While lost, a correlation peak of this quality away from the prediction
        moves the superpixel search there (the inliers verify it).
    cf_learn_above, cf_learning_rate, cf_padding, cf_window_cells
        The correlation filter learns from frames whose detection reached this
        quality, at this rate; its window is the box grown by ``cf_padding``,
        resampled to about ``cf_window_cells`` cells a side.
    cf_constrained, cf_colour_merge
        The filter is restricted to the target's cells (BACF) and its response
        merged with Staple's colour score at this weight
        (:class:`~vidtrack.measure.correlation.CorrelationFilter`).  Chosen
        with ``cf_motion`` on the tune split at seeds 0-2 (mean AUC): 0.591
        against 0.578 for the plain DSST filter of 3.5 boxes / 32 cells with
        ``cf_motion`` 0.2; ``cf_motion`` 0.02 / 0.1 / 0.2 / 0.5 with the new
        filter: 0.568 / 0.586 / 0.579 / 0.523.
    cf_options
        Further :class:`~vidtrack.measure.correlation.CorrelationFilter` options.
    global_after, global_every
        After this many lost frames, every ``global_every`` frames, the whole frame is searched.
    redetect
        Re-detection by the correlation filter (the whole-frame search and ``cf_reacquire``).
    cf_reuse_sample
        The correlation filter learns from its detection's window, shifted
        (:class:`~vidtrack.measure.correlation.CorrelationFilter` ``reuse_sample``).
    cf_present
        A frame with no usable measurement is still reported ``tracking``
        (predicted only) when the correlation filter's quality reaches this
        and its peak lies within half a box of the prediction: ``lost`` then
        means that neither cue sees the target there (None: any frame with no
        usable measurement is ``lost``).  Only the reported status changes:
        the search after a frame the filter only predicted (the bag growing
        with the covariance, re-detection) is the same either way, since it
        follows the filter's ``measured`` scalar, not the status.  Chosen on
        the tune split at seeds 0-2 (AUC unchanged, 0.594): frames marked lost
        whose box still overlaps the target ("false lost") 0.63 with None,
        0.21 / 0.25 / 0.31 at 0.3 / 0.5 / 0.7; tracking frames off the target
        ("missed loss") 0.006, 0.014 / 0.012 / 0.010.
    cf_thread
        Run the correlation filter (its update from the last frame, then its
        detection in this one) in a second thread while this one computes
        the superpixels, the SVM scores and the graph cut (they meet at the
        fusion).  Each task reads what it would read in one thread, so the
        results are the same as with ``False``; only the wall clock differs.
    svm_thread
        With ``cf_thread``, run the Pegasos updates in the second thread too
        (queued after the correlation filter's update; the next frame's
        superpixels do not need them, only its scores do), instead of in
        ``learn`` on this one.  Off by default since the correlation filter
        alone keeps the second thread busier than the superpixels keep this
        one; the results are the same either way.
    ncc_radius
        The refinement searches this fraction of the box size around the inlier-based centre.
    ncc_min
        A match at least this good (normalised cross-correlation) moves the
        centre and lets the running template learn.
    ncc_rate
        Learning rate of the running template (the first frame's template is kept too).
    ncc_motion
        Penalty on the squared displacement (template units) from the inlier-based centre.
    ncc_reacquire
        With no inliers, a match this good anywhere in the ``lam sigma`` window
        is the measurement (1 or more: never).
    ncc_floor
        The measurement's quality is scaled by ``(peak - ncc_floor) / (ncc_min - ncc_floor)``
        clipped to [0, 1] (None: not scaled).
    svm_average
        Score with the average of the Pegasos iterates of the last update
        (:class:`~vidtrack.learn.pegasos.PegasosSVM` ``average``).
    ncc_combine
        How the first frame's and the running template's NCC maps combine:
        ``"max"`` or ``"mean"`` (the first frame's template then keeps
        pulling a drifting running template back).
    """

    def __init__(self, *, lam: float = 3.0, pad: float = 0.6, max_extra: float = 1.0,
                 object_pixels: float = 40.0, superpixels_per_side: float = 3.5, slic_iterations: int = 4,
                 slic_ruler: float = 10.0, slic: str = "numba", positive_fraction: float = 0.7, negative_fraction: float = 0.3,
                 gamma_max: int = 25, update_every: int = 6, svm_lam: float = 1e-3, svm_iter: int = 40,
                 svm_init_iter: int = 1000, svm_max_t: int | None = 2000, svm_batch: int | None = 256,
                 keep_initial: bool = True, anchor_weight: int = 1,
                 bag_scale: float = 1.15, cut_slope: float = 2.0, cut_beta: float = 1.0,
                 feature_order: int = 1, min_inlier_fraction: float = 0.1, locate: str = "smoothed",
                 spatial_prior: float = 1.0, learn_above: float = 0.5,
                 size_coverage: float = 0.6, positive_margin: float = 0.0,
                 outliers_negative: bool = True, lost_bag: bool = True, refine: str = "cf",
                 ncc_radius: float = 0.3, ncc_min: float = 0.45, ncc_rate: float = 0.05,
                 ncc_motion: float = 0.4, ncc_reacquire: float = 0.7, ncc_floor: float | None = 0.45,
                 svm_average: bool = False, ncc_combine: str = "mean",
                 size_from: str = "cf", cf_min: float = 0.15, cf_motion: float = 0.05, cf_reacquire: float = 0.9,
                 cf_learn_above: float = 0.2, cf_learning_rate: float = 0.02, cf_padding: float = 4.0, cf_window_cells: int = 40,
                 cf_constrained: bool = True, cf_colour_merge: float = 0.3, cf_options: dict | None = None, global_after: int = 30, global_every: int = 5, redetect: bool = True,
                 cf_reuse_sample: bool = True, cf_present: float | None = 0.5,
                 cf_thread: bool = True, svm_thread: bool = False, rng: np.random.Generator | int | None = None) -> None:
        self.lam = lam
        self.pad = pad
        self.max_extra = max_extra
        self.object_pixels = object_pixels
        self.superpixels_per_side = superpixels_per_side
        self.slic_iterations = slic_iterations
        self.slic_ruler = slic_ruler
        self.slic = slic
        self.positive_fraction = positive_fraction
        self.negative_fraction = negative_fraction
        self.gamma_max = gamma_max
        self.update_every = update_every
        self.svm_lam = svm_lam
        self.svm_iter = svm_iter
        self.svm_init_iter = svm_init_iter
        self.svm_max_t = svm_max_t
        self.svm_batch = svm_batch
        self.keep_initial = keep_initial
        self.anchor_weight = anchor_weight
        self.bag_scale = bag_scale
        self.cut_slope = cut_slope
        self.cut_beta = cut_beta
        self.feature_order = feature_order
        self.min_inlier_fraction = min_inlier_fraction
        self.locate = locate
        self.spatial_prior = spatial_prior
        self.learn_above = learn_above
        self.size_coverage = size_coverage
        self.positive_margin = positive_margin
        self.outliers_negative = outliers_negative
        self.lost_bag = lost_bag
        self.refine = refine
        self.ncc_radius = ncc_radius
        self.ncc_min = ncc_min
        self.ncc_rate = ncc_rate
        self.ncc_motion = ncc_motion
        self.ncc_reacquire = ncc_reacquire
        self.ncc_floor = ncc_floor
        self.svm_average = svm_average
        self.ncc_combine = ncc_combine
        self.size_from = size_from
        self.cf_min = cf_min
        self.cf_motion = cf_motion
        self.cf_reacquire = cf_reacquire
        self.cf_learn_above = cf_learn_above
        self.cf_learning_rate = cf_learning_rate
        self.cf_padding = cf_padding
        self.cf_window_cells = cf_window_cells
        self.cf_constrained = cf_constrained
        self.cf_colour_merge = cf_colour_merge
        self.cf_options = dict(cf_options or {})
        self.global_after = global_after
        self.global_every = global_every
        self.redetect = redetect
        self.cf_reuse_sample = cf_reuse_sample
        self.cf_present = cf_present
        self.cf_thread = cf_thread
        self.svm_thread = svm_thread
        self.rng = rng
        self._worker: ThreadPoolExecutor | None = None
        self._cf_tasks: list[Future] = []
        self._svm_task: Future | None = None

    def __getstate__(self) -> dict:
        # the worker thread and its queue do not pickle (process pools, deepcopy): wait, then leave them out
        self._wait_all()
        state = dict(self.__dict__)
        state["_worker"], state["_cf_tasks"], state["_svm_task"] = None, [], None
        return state

    # -- helpers --------------------------------------------------------

    def _tic(self, name: str, start: float) -> float:
        now = time.perf_counter()
        self.timings_[name] += now - start
        return now

    def _submit(self, task, *args) -> Future:
        """``task(*args)`` on the worker thread, queued after the tasks before it (``cf_thread``), or run here now."""
        if not self.cf_thread:
            done: Future = Future()
            try:
                done.set_result(task(*args))
            except BaseException as exc:  # raised where the result is taken, as from the thread
                done.set_exception(exc)
            return done
        if self._worker is None:
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vidtrack-mil")
        return self._worker.submit(task, *args)

    def _result(self, tasks: list[Future], stage: str):
        """Wait for ``tasks`` in order (re-raising the first error); the last one's result (None: no task)."""
        t0 = time.perf_counter()
        result = None
        try:
            for task in tasks:
                result = task.result()
        finally:
            self._tic(stage, t0)
        return result

    def _wait_svm(self) -> None:
        """Wait for a Pegasos update running on the worker (the scores and the training set need it)."""
        task, self._svm_task = self._svm_task, None
        if task is not None:
            self._result([task], "svm (wait)")

    def _wait_correlation(self) -> CorrelationResult | None:
        tasks, self._cf_tasks = self._cf_tasks, []
        return self._result(tasks, "correlation (wait)") if tasks else None

    def _wait_all(self) -> None:
        self._wait_svm()
        self._wait_correlation()

    def _searching(self, prior: Estimate) -> bool:
        """The last frame was only predicted (lost, or kept ``tracking`` by ``cf_present``): search as when lost."""
        return prior.status == LOST or self.coasting_

    def _background_tic(self, name: str, start: float) -> None:
        """Time a worker task: in ``cf_timings_`` when it runs in the worker thread, else in ``timings_``."""
        (self.cf_timings_ if self.cf_thread else self.timings_)[name] += time.perf_counter() - start

    def _update_correlation(self, image: np.ndarray, box: Box) -> None:
        t0 = time.perf_counter()
        self.cf_.update(image, box)
        self._background_tic("correlation", t0)

    def _correlate(self, frame: Frame, prior: Estimate, whole_frame: bool) -> CorrelationResult:
        """The correlation filter's detection around the prior; with ``whole_frame``, around the frame's best peak.

        ``measure`` asks for the whole frame after ``global_after`` lost
        frames, every ``global_every`` frames: the target-only filter is slid
        over the whole frame and the window is searched around its best peak.
        Before that a loss is taken for an occlusion: only the window around
        the prediction is searched (a look-alike elsewhere must not take over
        while the target is hidden).  Runs on the worker: it reads only its arguments and the filter.
        """
        t0 = time.perf_counter()
        size = prior.box.size
        centre = prior.box.center
        if whole_frame:
            whole = np.array([frame.width, frame.height], float)
            centre = self.cf_.search(frame.image, whole / 2.0, whole, size).centre   # target only: no stale context
        result = self.cf_.detect(frame.image, centre, size)
        self._background_tic("correlation", t0)
        return result

    def _superpixels(self, frame: Frame, center, size, sigma):
        t0 = time.perf_counter()
        size = np.maximum(np.asarray(size, float), 4.0)
        extra = np.minimum(self.lam * np.asarray(sigma, float), self.max_extra * size)
        want = sp.search_box(center, size, extra, pad=self.pad)
        scale = min(1.0, self.object_pixels / float(np.sqrt(size[0] * size[1])))
        region = sp.cut_region(frame.image, want, scale=scale)
        if region is None:
            return None
        side = float(np.sqrt(size[0] * size[1])) * region.scale
        region_size = int(np.clip(round(side / self.superpixels_per_side), 4, 20))
        labels = sp.slic_labels(region.image, region_size=region_size, ruler=self.slic_ruler,
                                iterations=self.slic_iterations, implementation=self.slic)
        t0 = self._tic("superpixels", t0)
        K = int(labels.max()) + 1
        desc = sp.superpixel_descriptors(region.image, labels, K)
        features = sp.chi2_feature_map(desc, order=self.feature_order)
        self._tic("features", t0)
        return region, labels, desc, features

    def _templates(self, size: np.ndarray) -> list[np.ndarray]:
        """The initial and the running template at the current box size in region pixels."""
        tsize = (max(int(round(size[0])), 3), max(int(round(size[1])), 3))
        out = []
        for t in (self.template0_, self.template_):
            if t.shape[::-1] != tsize:
                t = cv2.resize(t, tsize, interpolation=cv2.INTER_LINEAR)
            out.append(t.astype(np.float32))
        return out

    def _add_triples(self, features: np.ndarray, labels: np.ndarray, t: int) -> None:
        keep = labels != 0
        if np.any(keep):
            self.buffer_.append((features[keep], labels[keep], t))

    def _train(self, n_iter: int, now: int, background: bool = True) -> None:
        """Pegasos on the training triples of the last ``gamma_max`` frames before frame ``now`` (and the anchor)."""
        t0 = time.perf_counter()
        horizon = now - self.gamma_max
        self.training_ = [(X, y, t) for X, y, t in self.training_ + self.buffer_ if t >= horizon]
        self.buffer_ = []
        sets = list(self.training_)
        if self.keep_initial:  # the anchor: the first frame's triples, repeated anchor_weight times
            sets.extend([self.initial_] * max(1, int(self.anchor_weight)))
        X = np.concatenate([s[0] for s in sets])
        y = np.concatenate([s[1] for s in sets])
        if np.any(y > 0) and np.any(y < 0):
            self.svm_.partial_fit(X, y, n_iter=n_iter)
        if background:
            self._background_tic("svm training", t0)
        else:
            self._tic("svm training", t0)

    # -- Measurer protocol -----------------------------------------------

    def initialize(self, frame: Frame, box: Box) -> None:
        """Bootstrap the SVM from the first frame: >= 70% inside the box positive, the rest negative (sec. 2.1)."""
        self._wait_all()
        self.timings_ = defaultdict(float)
        self.cf_timings_ = defaultdict(float)   # the correlation worker's stages (overlapping the others)
        self.svm_ = PegasosSVM(lam=self.svm_lam, n_iter=self.svm_iter, max_t=self.svm_max_t,
                               batch_size=self.svm_batch, average=self.svm_average, rng=self.rng)
        self.t_ = 0
        self.buffer_: list = []
        self.training_: list = []
        self.last_: _FrameData | None = None
        self.template0_ = self.template_ = None
        self.ncc_peak_ = -1.0
        self.cf_ = None
        self.cf_result_: CorrelationResult | None = None
        self.lost_run_ = 0
        self.coasting_ = False
        if self.refine == "cf" or self.size_from == "cf":
            t0 = time.perf_counter()
            self.cf_ = CorrelationFilter(learning_rate=self.cf_learning_rate, padding=self.cf_padding,
                                         window_cells=self.cf_window_cells, constrained=self.cf_constrained,
                                         colour_merge=self.cf_colour_merge, reuse_sample=self.cf_reuse_sample,
                                         **self.cf_options)
            self.cf_.initialize(frame.image, box)
            self._background_tic("correlation", t0)
        out = self._superpixels(frame, box.center, box.size, np.zeros(2))
        if out is None:
            self.initial_ = (np.zeros((0, 1)), np.zeros(0), 0)
            return
        region, labels, desc, features = out
        rbox = region.box_to_region(box)
        frac = sp.fraction_inside(labels, rbox)
        y = np.where(frac >= self.positive_fraction, 1, -1)
        if not np.any(y > 0):  # a box smaller than any superpixel: take the most-inside one
            y[np.argmax(frac)] = 1
        self.initial_ = (features, y, 0)
        # calibrate h: the positives' centroid and extent against the init box
        self.size_ratio_ = np.ones(2)
        self.centre_offset_ = np.zeros(2)
        if self.locate == "centroid":
            meas = inlier_measurement(labels, y > 0)
        else:
            meas = locate_inliers(labels, (y > 0).astype(float), rbox.size, rbox.center)
        if meas is not None:
            self.size_ratio_ = np.clip(rbox.size / meas[1], 0.5, 2.0)
            self.centre_offset_ = (rbox.center - meas[0]) / rbox.size
        self.training_ = [self.initial_]
        self._train(self.svm_init_iter, self.t_)
        if self.refine == "ncc":
            tsize = (max(int(round(rbox.w)), 3), max(int(round(rbox.h)), 3))
            patch = cut_patch(to_gray(region.image), rbox.center, tsize)
            if patch is not None and float(patch.std()) > 1e-3:
                self.template0_, self.template_ = patch, patch.copy()
        self.training_ = [] if self.keep_initial else self.training_

    def _find_inliers(self, frame: Frame, prior: Estimate, sigma: np.ndarray):
        """Superpixels of the search region around ``prior``, their SVM scores and the graph cut's inliers.

        Returns ``(region, labels, features, scores, inliers, region_box, extra)``
        (``region_box`` the prior's box and ``extra`` the ``lam sigma`` margin,
        both in region pixels), or None when the region leaves the frame.
        """
        out = self._superpixels(frame, prior.box.center, prior.box.size, sigma)
        if out is None:
            return None
        region, labels, desc, features = out
        self._wait_svm()
        t0 = time.perf_counter()
        scores = self.svm_.decision_function(features)
        t0 = self._tic("svm", t0)

        K = len(scores)
        area, centroid = sp.label_stats(labels, K)
        region_box = region.box_to_region(prior.box)
        bag_box = region.box_to_region(prior.box.scaled(self.bag_scale))
        norm = region_box.size
        extra = np.minimum(self.lam * sigma, self.max_extra * prior.box.size) * region.scale
        if self.lost_bag and self._searching(prior):  # eq. 8: while lost, look wherever the prediction may be
            bag_box = Box(bag_box.x - extra[0], bag_box.y - extra[1], bag_box.w + 2 * extra[0],
                          bag_box.h + 2 * extra[1])
            norm = norm + 2.0 * extra
        in_bag = ((centroid[:, 0] >= bag_box.x) & (centroid[:, 0] <= bag_box.x + bag_box.w)
                  & (centroid[:, 1] >= bag_box.y) & (centroid[:, 1] <= bag_box.y + bag_box.h))
        pairs, lengths = sp.adjacency(labels)
        cut_scores = scores
        if self.spatial_prior > 0:
            rel = (centroid - region_box.center) / norm * 2.0
            cut_scores = scores - self.spatial_prior * np.sum(rel ** 2, axis=1)
        inliers = select_inliers(cut_scores, desc, pairs, lengths, in_bag, slope=self.cut_slope,
                                 beta=self.cut_beta, area=area)
        self._tic("graphcut", t0)
        return region, labels, features, scores, inliers, region_box, extra

    def measure(self, frame: Frame, prior: Estimate) -> Superpixels | None:
        """Superpixels of the search region, SVM scores, graph-cut inliers and the inlier box."""
        self.t_ += 1
        self.last_ = None
        sigma = np.zeros(2)
        if prior.covariance is not None:
            sigma = np.sqrt(np.maximum(np.diag(prior.covariance)[:2], 0.0))
        searching = self._searching(prior)
        self.lost_run_ = self.lost_run_ + 1 if searching else 0
        whole_frame = (searching and self.redetect and self.lost_run_ >= self.global_after
                       and self.lost_run_ % max(self.global_every, 1) == 0)
        # the correlation filter (a second thread, see cf_thread) and the superpixel side run side by side
        if self.cf_ is not None:
            self._cf_tasks.append(self._submit(self._correlate, frame, prior, whole_frame))
        found = self._find_inliers(frame, prior, sigma)
        cf = self._wait_correlation()
        self.cf_result_ = cf
        if (cf is not None and self.redetect and searching and cf.quality >= self.cf_reacquire
                and np.linalg.norm(cf.centre - prior.box.center) > 0.5 * prior.box.scale):
            # re-detection: the correlation filter proposes, the superpixels and the SVM verify there
            prior = replace(prior, box=Box.from_center(*cf.centre, *prior.box.size))
            found = self._find_inliers(frame, prior, sigma)
        if found is None:
            return None
        region, labels, features, scores, inliers, region_box, extra = found
        grey = None
        self.ncc_peak_ = -1.0
        box = None
        quality = 0.0
        expected = max(region_box.area, 1.0)
        if self.locate == "centroid":
            meas = inlier_measurement(labels, inliers)
        else:
            meas = locate_inliers(labels, inliers.astype(float), region_box.size, region_box.center)
        if meas is not None:
            centre, size, mass = meas
            fraction = mass / expected
            if fraction >= self.min_inlier_fraction:
                margin = float(np.mean(scores[inliers]))
                quality = float(min(1.0, fraction / 0.5) / (1.0 + np.exp(-3.0 * margin)))
                quality = float(np.clip(quality * 2.0, 0.0, 1.0))
                size = size * self.size_ratio_  # calibrated extent (see initialize)
                if fraction < self.size_coverage:  # a partial inlier set does not measure the extent
                    size = region_box.size
                centre = centre + self.centre_offset_ * size
                if self.template_ is not None:  # extension: NCC refinement of the inlier-based centre
                    grey = to_gray(region.image)
                    found = match_templates(grey, self._templates(region_box.size), centre,
                                            self.ncc_radius * region_box.size, motion_weight=self.ncc_motion,
                                            combine=self.ncc_combine)
                    self.ncc_peak_ = -1.0 if found is None else found[1]
                    if self.ncc_peak_ >= self.ncc_min:
                        centre = found[0]
                    if self.ncc_floor is not None:  # a poor match (occlusion): trust the prediction more
                        quality *= float(np.clip((self.ncc_peak_ - self.ncc_floor)
                                                 / max(self.ncc_min - self.ncc_floor, 1e-6), 0.0, 1.0))
                fx, fy = region.to_frame(centre[0], centre[1])
                # the paper's h_2: the inlier extent ("inliers"); otherwise the prediction's size unless the
                # correlation filter's scale estimate replaces it below
                size = size / region.scale if self.size_from == "inliers" else prior.box.size
                if cf is not None:  # extension: fuse with the correlation filter's response
                    if self.refine == "cf" and cf.quality >= self.cf_min:
                        fx, fy = fuse_peak(cf, np.array([fx, fy]), self.cf_motion, prior.box.scale)
                    quality *= float(np.clip(cf.quality / max(self.cf_min, 1e-6), 0.0, 1.0))
                    if self.size_from == "cf" and cf.quality >= self.cf_min:
                        size = cf.size
                box = Box.from_center(float(fx), float(fy), float(size[0]), float(size[1]))
        if box is None and self.template_ is not None and self.ncc_reacquire < 1.0:
            # no inliers: look for the template wherever the prediction may be (lam sigma)
            grey = to_gray(region.image)
            size = region_box.size
            found = match_templates(grey, self._templates(size), region_box.center,
                                    extra + self.ncc_radius * size, motion_weight=self.ncc_motion,
                                    combine=self.ncc_combine)
            if found is not None and found[1] >= self.ncc_reacquire:
                centre, self.ncc_peak_ = found
                quality = float(found[1])
                fx, fy = region.to_frame(centre[0], centre[1])
                box = Box.from_center(float(fx), float(fy), size[0] / region.scale, size[1] / region.scale)
        self.last_ = _FrameData(region, labels, features, inliers, scores, grey)
        stages = {
            "superpixels": labels,
            "svm_scores": scores[labels].astype(np.float32),
            "inliers": inliers[labels].astype(np.uint8),
        }
        if cf is not None:
            stages["correlation"] = cf.response.astype(np.float32)
        present = (cf is not None and self.cf_present is not None and cf.quality >= self.cf_present
                   and np.linalg.norm(cf.centre - prior.box.center) <= 0.5 * prior.box.scale)
        return Superpixels(labels=labels, features=features, scores=scores, inliers=inliers, box=box,
                           quality=quality, search_region=region.box, stages=stages, present=bool(present))

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        """Relabel this frame's superpixels from the posterior (eq. 5) and update ``w`` every few frames.

        Positives: inliers with at least ``positive_fraction`` of their area in
        the posterior box; negatives: superpixels with at most
        ``negative_fraction`` inside it.  Nothing is learned while lost.
        """
        self._wait_svm()   # the training set is not touched while Pegasos runs on the worker
        self.coasting_ = posterior.scalars.get("measured", 1.0) == 0.0
        data = self.last_
        confident = data is not None and posterior.status == TRACKING and posterior.confidence >= self.learn_above
        cf = self.cf_result_
        if confident and cf is not None and cf.quality >= self.cf_learn_above:
            # first: the second thread's update and the next frame's detection are the longer path
            self._cf_tasks.append(self._submit(self._update_correlation, frame.image, posterior.box))
        if confident:
            frac = sp.fraction_inside(data.labels, data.region.box_to_region(posterior.box), len(data.scores))
            y = np.zeros(len(frac), dtype=int)
            y[(frac >= self.positive_fraction) & data.inliers & (data.scores > self.positive_margin)] = 1
            y[frac <= self.negative_fraction] = -1
            if self.outliers_negative:  # eq. 5: the cut's outliers inside the box are negatives
                y[(frac > self.negative_fraction) & ~data.inliers & (data.scores < 0)] = -1
            self._add_triples(data.features, y, self.t_)
            if data.grey is not None and self.ncc_peak_ >= self.ncc_min and self.ncc_rate > 0:
                rbox = data.region.box_to_region(posterior.box)
                patch = cut_patch(data.grey, rbox.center, self.template_.shape[::-1])
                if patch is not None:
                    self.template_ = (1.0 - self.ncc_rate) * self.template_ + self.ncc_rate * patch
        if self.t_ % self.update_every == 0 and self.buffer_:
            if self.svm_thread:   # on the worker (after the filter's update): the next frame's superpixels do not need w
                self._svm_task = self._submit(self._train, self.svm_iter, self.t_)
            else:                 # here, while the second thread updates the correlation filter
                self._train(self.svm_iter, self.t_, background=False)


# Load the compiled kernel at import, not inside the first tracked frame (see vidtrack.measure.slic).
locate_inliers(np.zeros((4, 4), np.int64), np.ones(1), np.array([2.0, 2.0]), np.array([2.0, 2.0]))
