"""A discriminative correlation filter on HOG and colour cells, with a scale search.

The filter is the multi-channel linear correlation filter of the MOSSE/DSST
family (Bolme et al., "Visual Object Tracking using Adaptive Correlation
Filters"; Danelljan et al., "Accurate Scale Estimation for Robust Visual
Tracking"); its equations (DSST eqs. 4-6) are the pure functions of
:mod:`vidtrack.measure.dcf`.  The features of a window are the cells of
:func:`vidtrack.measure.features.cell_features` (HOG and Lab), times a
cosine window.

Everything is measured in units of the target box: the window is the box
grown by ``padding`` and resampled so that its square-root area spans
``window_cells`` cells, whatever the frame size, so the cost per frame is
constant and a 640x480 video behaves like a 320x240 one.  Scale is
estimated at the detected centre by DSST's separate 1-D scale filter
(:class:`~vidtrack.measure.scale_filter.ScaleFilter`); the alternative, the
same translation filter evaluated at a few scales per frame (SAMF's search,
``scale_factors`` with non-unit scales discounted by ``scale_penalty``), is
kept as an option.

The departures from DSST, each a field of :class:`CorrelationConfig` and
all on by default:

* ``constrained``: the filter is restricted to the target's own cells (the
  central ``support`` of the box's sides) and learned by ADMM on every
  shift of the window (:func:`~vidtrack.measure.dcf.constrained_filter`,
  Kiani Galoogahi et al., "Learning Background-Aware Correlation Filters
  for Visual Tracking"), so the static background a wide window holds
  cannot outvote a small moving target;
* ``second_moment``: that filter fits every past sample, faded at the
  learning rate, instead of their average (ECO's objective, Danelljan et
  al., "ECO: Efficient Convolution Operators for Tracking", eq. 3), through
  the samples' running second moment per frequency
  (:mod:`vidtrack.measure.sample_moments`); it is solved every
  ``solve_interval`` frames, the samples gathered at each (ECO's sparse
  updates);
* ``colour_merge``: the response is merged with the colour-histogram score
  of Staple (Bertinetto et al., "Staple: Complementary Learners for
  Real-Time Tracking"; :mod:`vidtrack.measure.colour_model`);
* ``reuse_sample``: the filter learns from the window its detection has
  just cut, shifted in the Fourier domain, instead of a second, re-cut
  window (one feature extraction a frame instead of two).

The quality of a response is a peak-to-sidelobe ratio (Bolme et al.):
``(peak - mean) / std`` of the response outside a small area around the
peak, mapped linearly from ``psr_low`` (no target: 0) to ``psr_high`` (1);
by default it is measured on the response of the filter restricted to the
target's own cells (``quality_from="target"``).  :meth:`CorrelationFilter.search`
slides that target-only filter over a large region for re-detection.

The defaults are those of ``mil``'s filter; the score-map detector
(:mod:`vidtrack.measure.correlation_score_map`) states where it differs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from scipy import fft

from ..config import option
from ..types import Box
from .colour_model import ColourHistogramModel, colour_bins
from .dcf import (constrained_filter, correlation_response, cosine_window, dcf_terms, gaussian_response,
                  peak_to_sidelobe, running_average, shift_cells, subpixel_peak)
from .features import cell_features
from .image import cut_window
from .sample_moments import accumulate_second_moment
from .scale_filter import ScaleFilter


@dataclass(frozen=True)
class CorrelationConfig:
    """The configuration of a :class:`CorrelationFilter` (the defaults: ``mil``'s filter)."""

    padding: float = option(4.0, "the window is the box grown by this factor: (1 + padding) box sides")
    window_cells: int = option(40, "the window's square-root area in cells (its resolution, whatever the frame)")
    cell: int = option(4, "cell side in resampled pixels", minimum=1)
    sigma_factor: float = option(0.1, "width of the desired Gaussian response, fraction of the box's sqrt(w h)")
    lam: float = option(1e-2, "regulariser lambda of the filter (DSST eq. 4)")
    learning_rate: float = option(0.02, "eta, the rate of the running model (DSST eq. 5)")
    scale_factors: tuple[float, ...] = option((1.0,), "scales the translation filter searches per frame "
                                                      "(SAMF's search; 1: scale is left to the scale filter)")
    scale_penalty: float = option(0.985, "multiplier on the peak of every searched scale other than 1")
    scale_filter: bool = option(True, "estimate the scale change with DSST's 1-D scale filter at the detected centre")
    scale_count: int = option(ScaleFilter.n_scales, "scales of the scale filter's sample (DSST: 33)", minimum=3)
    scale_step: float = option(ScaleFilter.step, "ratio between neighbouring scales of the scale filter's sample",
                               above=1.0)
    scale_rate: float = option(ScaleFilter.learning_rate, "learning rate of the scale filter", above=0.0)
    scale_area: float = option(2048.0, "pixels each scale of the scale filter's sample is resampled to (DSST: 512)",
                               above=0.0)
    psr_low: float = option(3.0, "peak-to-sidelobe ratio mapped to quality 0")
    psr_high: float = option(10.0, "peak-to-sidelobe ratio mapped to quality 1")
    colour: bool = option(True, "Lab colour cells beside HOG")
    exclude_cells: int = option(2, "half-side of the square around the peak left out of the PSR's sidelobe")
    quality_from: Literal["target", "full"] = option(
        "target", "the PSR of the filter restricted to the box's cells (target) or of the full response")
    colour_merge: float = option(0.3, "Staple's alpha: weight of the colour-histogram score in the response "
                                      "(0: the filter alone)")
    colour_bins: int = option(32, "levels per channel of the colour histograms")
    colour_rate: float = option(0.04, "learning rate of the colour histograms")
    constrained: bool = option(True, "learn the filter restricted to the target's cells by ADMM (BACF) "
                                     "instead of DSST's running numerator and denominator")
    admm_iterations: int = option(4, "ADMM iterations per solve (five times as many on the first)")
    admm_mu: float = option(0.01, "ADMM penalty, relative to the model's spectral energy")
    second_moment: bool = option(True, "learn the constrained filter from every past sample, faded (their running "
                                        "second moment: ECO's objective), instead of from their average")
    solve_interval: int = option(3, "the constrained filter is solved at every this many updates; its samples are "
                                    "gathered at each (ECO's sparse updates)", minimum=1)
    support: float = option(0.85, "the target's cells, where the constrained filter may be non-zero: this fraction "
                                 "of the box's sides at the window's centre", above=0.0)
    reuse_sample: bool = option(True, "learn from the detection's window shifted in the Fourier domain "
                                      "instead of a re-cut one")
    reuse_tolerance: float = option(0.1, "the detection's window is reused when the learned box's size is "
                                         "within this fraction of the searched size")


def make_scale_filter(config: CorrelationConfig) -> ScaleFilter | None:
    """The :class:`~vidtrack.measure.scale_filter.ScaleFilter` of ``config`` (None when ``scale_filter`` is off)."""
    if not config.scale_filter:
        return None
    return ScaleFilter(n_scales=config.scale_count, step=config.scale_step, learning_rate=config.scale_rate,
                       model_area=config.scale_area, colour=config.colour)


@dataclass(frozen=True)
class CorrelationResult:
    """The detector's answer for one window.

    ``centre`` and ``size`` in frame pixels (size = the searched size times
    the winning scale factor); ``response`` ``(h, w)`` over the window
    centred on ``window_centre``: cell ``(i, j)`` is the box centred at
    ``window_centre + ((j - w // 2) step, (i - h // 2) step)``; ``step``
    frame pixels per response cell; ``scale`` the winning factor; ``peak``,
    ``psr`` and ``quality`` in ``[0, 1]`` (from the PSR).
    """

    window_centre: np.ndarray
    centre: np.ndarray
    size: np.ndarray
    response: np.ndarray
    step: float
    scale: float
    peak: float
    psr: float
    quality: float


class CorrelationFilter:
    """Multi-channel DCF on HOG + Lab cells with a scale search; see the module docstring.

    ``colour_merge``: the response located is ``(1 - alpha)`` times the
    filter's plus ``alpha`` times the colour-histogram score of
    :class:`~vidtrack.measure.colour_model.ColourHistogramModel` (Staple's
    merge, its eq. 22); the quality stays the filter's.  ``constrained``:
    the filter is learned by :func:`~vidtrack.measure.dcf.constrained_filter`
    from a running average of the window's features (rate
    ``learning_rate``).  ``reuse_sample``: :meth:`update` learns from the
    window :meth:`detect` has just cut (its features shifted in the Fourier
    domain so that the learned box is at the centre, the colour masks moved
    by the same shift) when the learned box is within ``reuse_tolerance``
    (relative) of the searched size and a quarter window of its centre; the
    shifted sample's cosine taper and border differ from a re-cut one by the
    shift.

    Parameters
    ----------
    config
        The filter's :class:`CorrelationConfig`.
    """

    def __init__(self, config: CorrelationConfig = CorrelationConfig()) -> None:
        self.config = config

    # -- geometry -----------------------------------------------------

    def _layout(self, box_size: np.ndarray) -> None:
        """Window shape in cells, following the init box's aspect ratio (fixed from then on)."""
        c = self.config
        window = np.asarray(box_size, float) * (1.0 + c.padding)
        aspect = np.clip(window[0] / max(window[1], 1e-6), 0.25, 4.0)
        wc = max(int(round(c.window_cells * np.sqrt(aspect))), 8)
        hc = max(int(round(c.window_cells / np.sqrt(aspect))), 8)
        self.shape_ = (hc, wc)                                  # cells (rows, columns)
        self.out_size_ = (wc * c.cell, hc * c.cell)             # resampled pixels (w, h)

    def cell_step(self, box_size) -> float:
        """Frame pixels per cell for a box of ``box_size``: the window covers ``(1 + padding)`` boxes, square cells."""
        hc, wc = self.shape_
        b = np.asarray(box_size, float) * (1.0 + self.config.padding)
        return float(max(b[0] / wc, b[1] / hc))

    def window_size(self, box_size) -> np.ndarray:
        """The window ``(w, h)`` in frame pixels around a box of ``box_size``."""
        return self.cell_step(box_size) * np.array([self.shape_[1], self.shape_[0]], float)

    def features(self, patch: np.ndarray) -> np.ndarray:
        """Windowed cell features ``(h, w, d)`` of a window resampled to ``out_size_``."""
        return self.taper(cell_features(patch, cell=self.config.cell, colour=self.config.colour))

    def taper(self, features: np.ndarray) -> np.ndarray:
        """Cell features ``(h, w, d)`` of a window times the cosine window."""
        return features * self.cos_[:, :, None]

    def patch(self, image: np.ndarray, centre, box_size) -> np.ndarray:
        """The window around ``centre`` for a box of ``box_size``, resampled to ``out_size_`` pixels."""
        return cut_window(image, centre, self.window_size(box_size), self.out_size_)

    # -- protocol -----------------------------------------------------

    def initialize(self, image: np.ndarray, box: Box) -> None:
        """Learn the filter from the first frame's box."""
        c = self.config
        self._layout(box.size)
        self.cos_ = cosine_window(self.shape_).astype(np.float32)
        box_cells = box.scale / self.cell_step(box.size)
        self.box_cells_ = box.size / self.cell_step(box.size)     # the box's (w, h) in cells
        self.mask_ = self.target_mask()
        self.target_fft_ = fft.rfft2(gaussian_response(self.shape_, c.sigma_factor * box_cells).astype(np.float32))
        self.numerator_ = self.denominator_ = self.model_fft_ = self.admm_state_ = self.moment_ = None
        self.updates_since_solve_ = 0
        self.last_sample_ = None
        self.scale_ = make_scale_filter(c)
        self.colour_model_ = (ColourHistogramModel(bins=c.colour_bins, learning_rate=c.colour_rate)
                              if c.colour_merge > 0 else None)
        if self.scale_ is not None:
            self.scale_.initialize(image, box)
        self.update(image, box, rate=1.0)

    def update(self, image: np.ndarray, box: Box, *, rate: float | None = None) -> None:
        """Learn from the window around ``box`` (DSST eq. 5), and the scale filter from the box."""
        c = self.config
        rate = c.learning_rate if rate is None else rate
        learned = self.numerator_ is not None or self.model_fft_ is not None   # not the first sample
        if self.scale_ is not None and learned:
            self.scale_.update(image, box, rate=None if rate < 1.0 else rate)
        sample, self.last_sample_ = self.last_sample_, None
        shift = self._reusable_shift(sample, box) if c.reuse_sample else None
        colour_rate = None if rate < 1.0 else rate
        if shift is None:
            patch = self.patch(image, box.center, box.size)
            if self.colour_model_ is not None:
                self.colour_model_.update(patch, self.box_cells_ * c.cell, rate=colour_rate)
            f = fft.rfft2(self.features(patch), axes=(0, 1))
        else:   # the detection's window, shifted so that the learned box is at its centre
            _, _, patch, raw, index = sample
            if self.colour_model_ is not None:
                self.colour_model_.update(patch, self.box_cells_ * c.cell, rate=colour_rate,
                                          offset=shift * c.cell, index=index)
            f = fft.rfft2(self.taper(shift_cells(raw, shift)), axes=(0, 1))
        if c.constrained:
            if not self._learn_constrained(f, rate):
                return
        else:
            num, den = dcf_terms(f, self.target_fft_)
            self.numerator_, self.denominator_ = running_average((self.numerator_, self.denominator_), (num, den), rate)
            self.filter_fft_ = self.numerator_ / (self.denominator_ + c.lam)[:, :, None]
        if c.quality_from == "target":
            self.target_filter_fft_ = fft.rfft2(self.spatial_filter(target_only=True), axes=(0, 1))

    def _learn_constrained(self, f: np.ndarray, rate: float) -> bool:
        """Gather the sample spectrum ``f`` and, every ``solve_interval`` updates (and at a restart), solve by ADMM.

        Returns whether the filter was solved (it is otherwise unchanged).
        """
        c = self.config
        self.model_fft_ = running_average((self.model_fft_,), (f,), rate)[0]
        if c.second_moment:
            if self.moment_ is None or rate >= 1.0:
                self.moment_ = np.zeros(f.shape + f.shape[-1:], np.complex128)
            accumulate_second_moment(self.moment_, f, rate)
        first = self.admm_state_ is None
        self.updates_since_solve_ += 1
        if not first and rate < 1.0 and self.updates_since_solve_ < c.solve_interval:
            return False
        self.updates_since_solve_ = 0
        self.filter_fft_, *state = constrained_filter(
            self.model_fft_, self.target_fft_, self.mask_, self.shape_, lam=c.lam,
            iterations=c.admm_iterations * (5 if first else 1), mu=c.admm_mu, start=self.admm_state_,
            moment=self.moment_)
        self.admm_state_ = tuple(state)
        return True

    def window(self, image: np.ndarray, centre, box_size, scale: float = 1.0) -> tuple:
        """The sample :meth:`respond` correlates: ``(centre, size, patch, raw cell features, colour bins, spectrum)``.

        It depends on the image and the filter's fixed layout alone, not on
        what the filter has learned, so it may be cut while an :meth:`update`
        is still running (``mil`` cuts it on its main thread while the second
        thread learns).
        """
        c = self.config
        size = np.asarray(box_size, float) * scale
        patch = self.patch(image, centre, size)
        raw = cell_features(patch, cell=c.cell, colour=c.colour)
        z = fft.rfft2(self.taper(raw), axes=(0, 1))
        index = colour_bins(patch, self.colour_model_.bins) if self.colour_model_ is not None else None
        return np.asarray(centre, float), size, patch, raw, index, z

    def respond(self, image: np.ndarray, centre, box_size, scale: float = 1.0, *, window: tuple | None = None
                ) -> tuple[np.ndarray, np.ndarray, tuple]:
        """The circular response of the window of ``box_size * scale`` around ``centre``, its spectrum and sample.

        The sample ``(centre, size, patch, raw cell features, colour bins)`` is
        what :meth:`update` reuses (``reuse_sample``); ``window``, the same
        window's :meth:`window` when already cut.

        With ``colour_merge`` the response is Staple's merge (eq. 22) of the
        filter's and the colour histograms' (at the same shifts).
        """
        c = self.config
        centre, size, patch, raw, index, z = self.window(image, centre, box_size, scale) if window is None else window
        response = correlation_response(self.filter_fft_, z, self.shape_)
        if self.colour_model_ is not None:
            colour = self.colour_model_.response(patch, self.box_cells_ * c.cell, self.shape_, c.cell,
                                                 index=index)
            a = c.colour_merge
            response = fft.ifftshift((1.0 - a) * fft.fftshift(response) + a * colour)
        return response, z, (centre, size, patch, raw, index)

    def _reusable_shift(self, sample, box: Box) -> np.ndarray | None:
        """The shift ``(dx, dy)`` in cells from ``sample``'s window centre to ``box``, if the window can be reused."""
        if sample is None:
            return None
        centre, size, *_ = sample
        if np.any(np.abs(box.size / np.maximum(size, 1e-9) - 1.0) > self.config.reuse_tolerance):
            return None
        shift = (box.center - centre) / self.cell_step(size)
        if np.any(np.abs(shift) > 0.25 * np.array([self.shape_[1], self.shape_[0]])):
            return None
        return shift

    def _quality(self, psr: float) -> float:
        """The PSR mapped linearly from ``psr_low`` (0) to ``psr_high`` (1), clipped."""
        c = self.config
        return float(np.clip((psr - c.psr_low) / (c.psr_high - c.psr_low), 0.0, 1.0))

    def detect(self, image: np.ndarray, centre, box_size, *, scales: tuple[float, ...] | None = None,
               window: tuple | None = None) -> CorrelationResult:
        """Search the window around ``centre`` at each scale; the best peak is the detection.

        ``window``: the scale-1 window's :meth:`window`, when already cut.
        """
        c = self.config
        scales = c.scale_factors if scales is None else scales
        best = None
        for s in scales:
            response, z, sample = self.respond(image, centre, box_size, s, window=window if s == 1.0 else None)
            shift, index, peak = subpixel_peak(response)
            score = peak * (1.0 if s == 1.0 else c.scale_penalty)
            if best is None or score > best[0]:
                best = (score, s, response, shift, index, peak, z, sample)
        _, s, response, shift, index, peak, z, self.last_sample_ = best
        step = self.cell_step(np.asarray(box_size, float) * s)
        found = np.asarray(centre, float) + shift * step
        if self.scale_ is not None and len(scales) == 1:   # DSST: the scale filter at the new position
            s = s * self.scale_.estimate(image, found, np.asarray(box_size, float) * s)
        size = np.asarray(box_size, float) * s
        measured = response
        if c.quality_from == "target":   # is the target itself there? (the context may match without it)
            measured = correlation_response(self.target_filter_fft_, z, self.shape_)
        psr = peak_to_sidelobe(measured, index, c.exclude_cells)
        return CorrelationResult(window_centre=np.asarray(centre, float), centre=found, size=size,
                                 response=fft.fftshift(response), step=step, scale=float(s), peak=peak,
                                 psr=psr, quality=self._quality(psr))

    def spatial_filter(self, *, target_only: bool = True) -> np.ndarray:
        """The learned filter in the spatial domain, ``(h, w, d)`` cells, target at the window centre.

        ``target_only`` zeroes it outside the box's own cells: for
        re-detection, where the context the filter learned (a static
        background) would otherwise fire at the place the target left.
        """
        h = fft.irfft2(self.filter_fft_, s=self.shape_, axes=(0, 1)).astype(np.float32)
        if target_only:
            h *= self.mask_[:, :, None]
        return h

    def target_mask(self) -> np.ndarray:
        """``(h, w)`` float32: 1 on the box's central ``support`` of cells (rounded out) at the window's centre, 0 elsewhere."""
        hc, wc = self.shape_
        half = np.ceil(self.box_cells_ * self.config.support / 2.0).astype(int)
        mask = np.zeros((hc, wc), np.float32)
        mask[max(hc // 2 - half[1], 0):hc // 2 + half[1] + 1, max(wc // 2 - half[0], 0):wc // 2 + half[0] + 1] = 1
        return mask

    def search(self, image: np.ndarray, centre, region_size, box_size) -> CorrelationResult:
        """Re-detection over a large region: the filter slid over every cell of ``region_size`` around ``centre``.

        The region (any size, e.g. the whole frame) is resampled at the
        filter's resolution for ``box_size`` and its cell features
        (no cosine window) are correlated with :meth:`spatial_filter`
        (``cv2.filter2D``, zero outside the image), so the cost grows with the
        region's area in box units, not with the frame.  The response is not
        circular; its PSR is measured in the same way.
        """
        c = self.config
        step = self.cell_step(box_size)
        frame = np.array([image.shape[1], image.shape[0]], float)
        # never more than the frame (plus a window): the cost and memory stay bounded however large the request
        region = np.clip(np.asarray(region_size, float), self.window_size(box_size), frame + self.window_size(box_size))
        cells = np.maximum(np.round(region / step).astype(int), 8)
        patch = cut_window(image, centre, cells * step, (int(cells[0]) * c.cell, int(cells[1]) * c.cell))
        z = cell_features(patch, cell=c.cell, colour=c.colour)
        h = self.spatial_filter()
        anchor = (self.shape_[1] // 2, self.shape_[0] // 2)
        response = np.zeros(z.shape[:2], np.float32)
        for channel in range(z.shape[2]):   # correlation: y(p) = sum_l sum_t h_l(t) z_l(p + t - anchor)
            response += cv2.filter2D(z[:, :, channel], -1, h[:, :, channel], anchor=anchor,
                                     borderType=cv2.BORDER_CONSTANT)
        r, col = np.unravel_index(int(np.argmax(response)), response.shape)
        peak = float(response[r, col])
        psr = peak_to_sidelobe(response, (int(r), int(col)), c.exclude_cells)
        found = np.asarray(centre, float) + (np.array([col, r], float) - cells // 2) * step
        return CorrelationResult(window_centre=np.asarray(centre, float), centre=found,
                                 size=np.asarray(box_size, float), response=response, step=step,
                                 scale=1.0, peak=peak, psr=psr, quality=self._quality(psr))
