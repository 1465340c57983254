"""Multiple Instance Filtering (Wnuk & Soatto): the paper's appearance side (superpixels, SVM, graph cut).

Model (sec. 1.2, eqs. 2 and 8 of the paper)::

    x(t+1) = F x(t) + v(t),          x = [c, v_c, d, v_d]   (centre, its velocity, size, its rate)
    w(t+1) = stochSubgradIters(w(t), y(t), O(t))          (Pegasos, vidtrack.learn.pegasos)
    O(t)   = argmin_O E(y(t), w(t), x(t), O)             (graph cut, vidtrack.learn.graphcut)
    h(y(t)_{i in O(t)}) = C x(t) + n(t)                  (centroid and extent of the inliers)

The state, ``F``, ``C`` and the Kalman filter are in
:mod:`vidtrack.filters.mil`.  :class:`MILAppearance` is the rest of the
paper: it cuts the search region (the prediction enlarged by ``lam = 3``
standard deviations of the predicted centre, eq. 8), computes SLIC
superpixels there, their descriptors and chi-squared feature maps
(:mod:`vidtrack.measure.superpixels`), the SVM scores, and the inliers by a
graph cut inside the positive bag; the measurement is the centroid and
extent of the inlier pixels (:func:`locate_inliers`,
:func:`inlier_measurement`).  After the filter's update it relabels the
frame's superpixels from the posterior (the semi-supervised loop of eq. 5)
into a training set of ``(descriptor, label, time)`` triples kept
``gamma_max = 25`` frames, and takes Pegasos steps every
``update_every = 6`` frames.  The measurer on the tracker's data path,
:class:`vidtrack.measure.mil_fusion.MILMeasurer`, runs it and fuses it with
a correlation filter (the extensions beyond the paper).

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
  inlier set is not the object's size, so the inlier extent (the paper's
  ``h_2``) is a size measurement only when the inliers cover
  ``size_coverage`` of the box, and the predicted size otherwise;
* the inlier centroid and extent are calibrated on the first frame: the
  offset and ratio between the positives' and the given box are applied to
  every later measurement.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import cv2
import numba
import numpy as np

from ..config import option
from ..learn.graphcut import select_inliers
from ..learn.pegasos import PegasosSVM
from ..types import TRACKING, Box, Estimate, Frame
from . import superpixels as sp
from .threads import tic

# ------------------------------------------------------------------ configuration


@dataclass(frozen=True)
class SuperpixelConfig:
    """The search region, its SLIC superpixels and their descriptors."""

    lam: float = option(3.0, "the search region covers lam standard deviations of the predicted centre "
                             "(eq. 8; the paper: 3)")
    pad: float = option(0.6, "context around the predicted box in the search region, fraction of its size a side")
    max_extra: float = option(1.0, "cap on lam sigma, fraction of the box size (bounds the region while lost)")
    object_pixels: float = option(40.0, "the region is resampled so the box's sqrt(w h) spans about this many "
                                        "pixels (never enlarged)")
    per_side: float = option(3.5, "about this many superpixels across the box side")
    iterations: int = option(4, "SLIC k-means iterations")
    ruler: float = option(10.0, "SLIC compactness")
    slic: Literal["numba", "opencv"] = option("numba", "SLIC implementation: numba (compiled, GIL-free) or "
                                                       "opencv (ximgproc: the same algorithm, other superpixels)")
    feature_order: int = option(1, "frequencies of the descriptors' chi-squared feature map (Vedaldi & Zisserman)")


@dataclass(frozen=True)
class SVMConfig:
    """The Pegasos SVM and its training set of ``(descriptor, label, time)`` triples."""

    lam: float = option(1e-3, "Pegasos regularisation lambda")
    iterations: int = option(40, "Pegasos iterations per update")
    initial_iterations: int = option(1000, "Pegasos iterations on the first frame")
    max_t: int | None = option(2000, "cap on Pegasos' step counter, so the step never falls below "
                                     "1/(lambda max_t) (none: the plain schedule)")
    batch: int | None = option(256, "Pegasos mini-batch size (none: the whole training set per iteration)")
    average: bool = option(False, "score with the mean of the last update's iterates instead of the last one")
    update_every: int = option(6, "frames between Pegasos updates (the paper: 6)")
    gamma_max: int = option(25, "frames a training triple is kept (the paper: 25)")
    keep_initial: bool = option(True, "keep the first frame's triples for ever (an anchor against drift)")
    anchor_weight: int = option(1, "times the first frame's triples count in every update")
    positive_fraction: float = option(0.7, "area fraction inside the box that makes a superpixel positive "
                                           "(the paper: 0.7)")
    negative_fraction: float = option(0.3, "a relabelled negative has at most this area fraction inside the box")
    positive_margin: float = option(0.0, "a relabelled positive must also score above this")
    outliers_negative: bool = option(True, "the cut's outliers inside the box with a negative score are "
                                           "relabelled negative (eq. 5)")
    learn_above: float = option(0.5, "frames whose posterior confidence is under this teach nothing")


@dataclass(frozen=True)
class GraphCutConfig:
    """The positive bag, the graph cut that selects the inliers, and the inlier measurement."""

    bag_scale: float = option(1.15, "the positive bag: superpixels whose centroid lies in the predicted box "
                                    "scaled by this")
    lost_bag: bool = option(True, "while lost, the bag and the spatial prior grow by lam sigma a side (eq. 8)")
    slope: float = option(2.0, "slope of the SVM-score sigmoid in the cut's unaries")
    beta: float = option(1.0, "weight of the cut's pairwise (appearance) terms")
    spatial_prior: float = option(1.0, "cost of an inlier per squared normalised distance from the predicted "
                                       "centre (0: SVM scores only)")
    min_inlier_fraction: float = option(0.1, "inliers covering less than this fraction of the box: no measurement")
    locate: Literal["smoothed", "centroid"] = option(
        "smoothed", "the measured box: at the peak of the smoothed inlier map (fig. 3) or the centroid of all inliers")
    size_coverage: float = option(0.6, "the inlier extent measures the size only when the inliers cover this "
                                       "fraction of the box")


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
    prior_u = np.empty(w)   # gentle preference for the prediction on ties: exp(-d^2 / 2) in box units
    for u in range(w):
        du = (u + 0.5 - start_u) / box_w
        prior_u[u] = np.exp(-0.5 * du * du)
    for v in range(h):
        dv = (v + 0.5 - start_v) / box_h
        prior_v = np.exp(-0.5 * dv * dv)
        for u in range(w):
            value = smooth[v, u] * (prior_v * prior_u[u])
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


# ------------------------------------------------------------------ the appearance model


@dataclass(frozen=True)
class InlierSearch:
    """One search for the inliers around a prediction: what :meth:`MILAppearance.learn` relabels.

    ``region`` the resampled search region; ``labels`` its ``(h, w)``
    superpixels, ``features`` their ``(K, D)`` feature maps, ``scores`` the
    SVM's ``(K,)`` scores, ``inliers`` the cut's ``(K,) bool`` selection and
    ``box`` the predicted box, all in region pixels.
    """

    region: sp.Region
    labels: np.ndarray
    features: np.ndarray
    scores: np.ndarray
    inliers: np.ndarray
    box: Box


@dataclass(frozen=True)
class InlierBox:
    """The inlier measurement in frame pixels: ``centre`` ``(x, y)``, the calibrated inlier ``size`` and a quality."""

    centre: tuple[float, float]
    size: np.ndarray
    quality: float
    coverage: float = 0.0


class MILAppearance:
    """Superpixels + Pegasos SVM + graph-cut inliers: the appearance side of Multiple Instance Filtering.

    Parameters
    ----------
    superpixels, svm, graphcut
        The configuration of its three parts.
    rng
        Generator, seed or None for Pegasos' mini-batches.
    """

    def __init__(self, superpixels: SuperpixelConfig = SuperpixelConfig(), svm: SVMConfig = SVMConfig(),
                 graphcut: GraphCutConfig = GraphCutConfig(), *,
                 rng: np.random.Generator | int | None = None) -> None:
        self.superpixels = superpixels
        self.svm = svm
        self.graphcut = graphcut
        self.rng = rng

    def initialize(self, frame: Frame, box: Box, *, timings: dict[str, float] | None = None) -> None:
        """Bootstrap the SVM from the first frame: >= 70% inside the box positive, the rest negative (sec. 2.1).

        ``timings`` (seconds per stage, added to) defaults to a new dict, ``timings_``.
        """
        s = self.svm
        self.timings_ = {} if timings is None else timings
        self.svm_ = PegasosSVM(lam=s.lam, n_iter=s.iterations, max_t=s.max_t, batch_size=s.batch,
                               average=s.average, rng=self.rng)
        self.t_ = 0
        self.buffer_: list = []
        self.training_: list = []
        self.size_ratio_ = np.ones(2)
        self.centre_offset_ = np.zeros(2)
        out = self._superpixels(frame, box.center, box.size, np.zeros(2))
        if out is None:
            self.initial_ = (np.zeros((0, 1)), np.zeros(0), 0)
            return
        region, labels, desc, features = out
        rbox = region.box_to_region(box)
        frac = sp.fraction_inside(labels, rbox)
        y = np.where(frac >= s.positive_fraction, 1, -1)
        if not np.any(y > 0):  # a box smaller than any superpixel: take the most-inside one
            y[np.argmax(frac)] = 1
        self.initial_ = (features, y, 0)
        # calibrate h: the positives' centroid and extent against the init box
        meas = self._locate(labels, y > 0, rbox)
        if meas is not None:
            self.size_ratio_ = np.clip(rbox.size / meas[1], 0.5, 2.0)
            self.centre_offset_ = (rbox.center - meas[0]) / rbox.size
        self.training_ = [self.initial_]
        self._train(s.initial_iterations, self.t_)
        self.training_ = [] if s.keep_initial else self.training_

    def search(self, frame: Frame, prior: Estimate, sigma: np.ndarray, *, searching: bool = False
               ) -> InlierSearch | None:
        """Superpixels of the search region around ``prior``, their SVM scores and the graph cut's inliers.

        ``sigma`` is the predicted centre's standard deviation ``(2,)``;
        ``searching`` (the target was not measured in the last frame) grows
        the positive bag with it (``lost_bag``).  None when the region leaves the frame.
        """
        g = self.graphcut
        out = self._superpixels(frame, prior.box.center, prior.box.size, sigma)
        if out is None:
            return None
        region, labels, desc, features = out
        t0 = time.perf_counter()
        scores = self.svm_.decision_function(features)
        t0 = tic(self.timings_, "svm", t0)

        K = len(scores)
        area, centroid = sp.label_stats(labels, K)
        region_box = region.box_to_region(prior.box)
        bag_box = region.box_to_region(prior.box.scaled(g.bag_scale))
        norm = region_box.size
        extra = np.minimum(self.superpixels.lam * sigma, self.superpixels.max_extra * prior.box.size) * region.scale
        if g.lost_bag and searching:  # eq. 8: while lost, look wherever the prediction may be
            bag_box = Box(bag_box.x - extra[0], bag_box.y - extra[1], bag_box.w + 2 * extra[0],
                          bag_box.h + 2 * extra[1])
            norm = norm + 2.0 * extra
        in_bag = ((centroid[:, 0] >= bag_box.x) & (centroid[:, 0] <= bag_box.x + bag_box.w)
                  & (centroid[:, 1] >= bag_box.y) & (centroid[:, 1] <= bag_box.y + bag_box.h))
        pairs, lengths = sp.adjacency(labels)
        cut_scores = scores
        if g.spatial_prior > 0:
            rel = (centroid - region_box.center) / norm * 2.0
            cut_scores = scores - g.spatial_prior * np.sum(rel ** 2, axis=1)
        inliers = select_inliers(cut_scores, desc, pairs, lengths, in_bag, slope=g.slope, beta=g.beta, area=area)
        tic(self.timings_, "graphcut", t0)
        return InlierSearch(region, labels, features, scores, inliers, region_box)

    def inlier_box(self, found: InlierSearch) -> InlierBox | None:
        """The paper's measurement ``h``: where the inliers are and their extent, with a quality in [0, 1].

        The quality grows with the inliers' share of the box (full at half
        of it) and their mean SVM margin; None when the inliers cover less
        than ``min_inlier_fraction`` of the box.
        """
        g = self.graphcut
        meas = self._locate(found.labels, found.inliers, found.box)
        if meas is None:
            return None
        centre, size, mass = meas
        fraction = mass / max(found.box.area, 1.0)
        if fraction < g.min_inlier_fraction:
            return None
        margin = float(np.mean(found.scores[found.inliers]))
        quality = float(min(1.0, fraction / 0.5) / (1.0 + np.exp(-3.0 * margin)))
        quality = float(np.clip(quality * 2.0, 0.0, 1.0))
        size = size * self.size_ratio_  # calibrated extent (see initialize)
        if fraction < g.size_coverage:  # a partial inlier set does not measure the extent
            size = found.box.size
        centre = centre + self.centre_offset_ * size
        fx, fy = found.region.to_frame(centre[0], centre[1])
        return InlierBox(centre=(fx, fy), size=size / found.region.scale, quality=quality, coverage=float(fraction))

    def confident(self, posterior: Estimate) -> bool:
        """Whether a frame with this posterior teaches the model (measured, of quality ``>= learn_above``).

        The filter's ``measured`` and ``quality`` scalars when it gives them
        (the reported status and confidence may be a calibrated judgement);
        else its status and confidence.
        """
        measured = posterior.scalars.get("measured", float(posterior.status == TRACKING))
        return bool(measured) and posterior.scalars.get("quality", posterior.confidence) >= self.svm.learn_above

    def learn(self, found: InlierSearch | None, box: Box) -> None:
        """One frame: relabel ``found`` from the posterior ``box`` (eq. 5), and update ``w`` every few frames.

        Positives: inliers with at least ``positive_fraction`` of their area in
        the box; negatives: superpixels with at most ``negative_fraction``
        inside it.  ``found`` None (nothing searched, or a frame that is not
        :meth:`confident`) adds no triple.
        """
        s = self.svm
        self.t_ += 1
        if found is not None:
            frac = sp.fraction_inside(found.labels, found.region.box_to_region(box), len(found.scores))
            y = np.zeros(len(frac), dtype=int)
            y[(frac >= s.positive_fraction) & found.inliers & (found.scores > s.positive_margin)] = 1
            y[frac <= s.negative_fraction] = -1
            if s.outliers_negative:  # eq. 5: the cut's outliers inside the box are negatives
                y[(frac > s.negative_fraction) & ~found.inliers & (found.scores < 0)] = -1
            keep = y != 0
            if np.any(keep):
                self.buffer_.append((found.features[keep], y[keep], self.t_))
        if self.t_ % s.update_every == 0 and self.buffer_:
            self._train(s.iterations, self.t_)

    # -- helpers --------------------------------------------------------

    def _locate(self, labels: np.ndarray, inliers: np.ndarray, box: Box):
        """:func:`locate_inliers` (``locate="smoothed"``) or :func:`inlier_measurement` of ``inliers``."""
        if self.graphcut.locate == "centroid":
            return inlier_measurement(labels, inliers)
        return locate_inliers(labels, inliers.astype(float), box.size, box.center)

    def _superpixels(self, frame: Frame, center, size, sigma):
        c = self.superpixels
        t0 = time.perf_counter()
        size = np.maximum(np.asarray(size, float), 4.0)
        extra = np.minimum(c.lam * np.asarray(sigma, float), c.max_extra * size)
        want = sp.search_box(center, size, extra, pad=c.pad)
        scale = min(1.0, c.object_pixels / float(np.sqrt(size[0] * size[1])))
        region = sp.cut_region(frame.image, want, scale=scale)
        if region is None:
            return None
        side = float(np.sqrt(size[0] * size[1])) * region.scale
        region_size = int(np.clip(round(side / c.per_side), 4, 20))
        labels = sp.slic_labels(region.image, region_size=region_size, ruler=c.ruler,
                                iterations=c.iterations, implementation=c.slic)
        t0 = tic(self.timings_, "superpixels", t0)
        K = int(labels.max()) + 1
        desc = sp.superpixel_descriptors(region.image, labels, K)
        features = sp.chi2_feature_map(desc, order=c.feature_order)
        tic(self.timings_, "features", t0)
        return region, labels, desc, features

    def _train(self, n_iter: int, now: int) -> None:
        """Pegasos on the training triples of the last ``gamma_max`` frames before frame ``now`` (and the anchor)."""
        s = self.svm
        t0 = time.perf_counter()
        horizon = now - s.gamma_max
        self.training_ = [(X, y, t) for X, y, t in self.training_ + self.buffer_ if t >= horizon]
        self.buffer_ = []
        sets = list(self.training_)
        if s.keep_initial:  # the anchor: the first frame's triples, repeated anchor_weight times
            sets.extend([self.initial_] * max(1, int(s.anchor_weight)))
        y = np.concatenate([item[1] for item in sets])
        if np.any(y > 0) and np.any(y < 0):
            self.svm_.partial_fit([item[0] for item in sets], y, n_iter=n_iter)   # stacked once, inside
        tic(self.timings_, "svm training", t0)


# Load the compiled kernel at import, not inside the first tracked frame (see vidtrack.measure.slic).
locate_inliers(np.zeros((4, 4), np.int64), np.ones(1), np.array([2.0, 2.0]), np.array([2.0, 2.0]))
