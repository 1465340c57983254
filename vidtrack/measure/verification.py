"""Appearance verification: does a box still look like the first frame's target?

A tracker's own scores come from the model it keeps updating, so when it
drifts onto the background that model drifts with it and its scores stay
high.  A verifier that never learns after the first frame does not: this
module compares each candidate box with the target as it was given, by two
cheap measures that do not depend on the tracker's model:

* the normalised cross-correlation of a small grey template of the first
  frame's box (about ``template_side`` pixels on a side) with the box's
  content at the same resolution (``cv2.matchTemplate``, ``TM_CCOEFF_NORMED``);
* the mean, over the box, of the first frame's colour likelihood
  ``P(target | colour) = h_o(c) / (h_o(c) + h_b(c))`` with ``h_o`` and
  ``h_b`` the colour histograms of the box and of the ring around it (the
  colour model of Possegger, Mauthner & Bischof, "In Defense of Color-based
  Model-free Tracking", CVPR 2015, learned once).

Both are computed over every box position of a region at once (a template
match and a box filter on a small resampled patch, well under a
millisecond) and returned as a :class:`~vidtrack.types.ScoreMap` of the NCC
whose ``stages["colour"]`` holds the colour score of the same positions.
:class:`VerifiedMeasurer` wraps any measurer and adds that map to each
measurement's ``stages["verification"]``, over the box positions within
``margin`` box sizes of the prior; the filters read it at their estimate
(:mod:`vidtrack.filters.confidence_cues`) without looking at pixels.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ..types import Box, Estimate, Frame, Measurement, ScoreMap
from .image import cut_window


def colour_indices(patch: np.ndarray, bins: int) -> np.ndarray:
    """Histogram bin index per pixel of a ``(H, W, 3)`` uint8 patch (``bins`` per channel) or ``(H, W)`` grey."""
    q = (patch.astype(np.int32) * bins) // 256
    if q.ndim == 2:
        return q
    return (q[..., 0] * bins + q[..., 1]) * bins + q[..., 2]


def box_means(values: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Mean of ``values`` over every ``size = (w, h)`` window; element ``[i, j]`` is the window at top-left ``(j, i)``."""
    w, h = size
    s = cv2.integral(values.astype(np.float64))
    return ((s[h:, w:] - s[:-h, w:] - s[h:, :-w] + s[:-h, :-w]) / float(w * h)).astype(np.float32)


class AppearanceVerifier:
    """The first frame's grey template and colour model, matched over a region; see the module docstring.

    Parameters
    ----------
    template_side
        Side, in pixels, of the square of the box's area at which the
        template is kept and matched.
    bins
        Colour histogram bins per channel (grey images: intensity bins ``bins ** 2``).
    """

    def __init__(self, template_side: int = 16, bins: int = 8) -> None:
        self.template_side = template_side
        self.bins = bins

    def _scale(self, size) -> float:
        return self.template_side / float(np.sqrt(max(size[0] * size[1], 1e-9)))

    def _template_size(self, size, s: float) -> tuple[int, int]:
        return max(4, int(round(size[0] * s))), max(4, int(round(size[1] * s)))

    def initialize(self, frame: Frame, box: Box) -> None:
        image = frame.image
        self.colour_ = image.ndim == 3
        self.n_bins_ = self.bins ** 3 if self.colour_ else self.bins ** 2
        s = self._scale(box.size)
        tw, th = self._template_size(box.size, s)
        # the box and a ring of one box size around it, at the template's resolution
        patch = cut_window(image, box.center, 3.0 * box.size, (3 * tw, 3 * th))
        grey = patch if patch.ndim == 2 else cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)
        self.template_ = grey[th:2 * th, tw:2 * tw].astype(np.float32)
        idx = colour_indices(patch, self.bins if self.colour_ else self.bins ** 2)
        inside = np.zeros(idx.shape, bool)
        inside[th:2 * th, tw:2 * tw] = True
        h_o = np.bincount(idx[inside], minlength=self.n_bins_).astype(float)
        h_b = np.bincount(idx[~inside], minlength=self.n_bins_).astype(float)
        h_o, h_b = h_o / h_o.sum(), h_b / h_b.sum()
        self.likelihood_ = ((h_o + 1e-4) / (h_o + h_b + 2e-4)).astype(np.float32)

    def verify(self, image: np.ndarray, region: Box, box_size, *, colour: bool = True) -> ScoreMap:
        """The verification map of the boxes of ``box_size`` whose top-left corners lie in ``region``.

        ``region`` covers the box positions (it is the union of the boxes);
        the map's scores are the template NCC in ``[-1, 1]`` and its
        ``stages["colour"]`` the mean colour likelihood in ``[0, 1]`` (with ``colour``).
        """
        s = self._scale(box_size)
        tw, th = self._template_size(box_size, s)
        template = self.template_
        if template.shape != (th, tw):
            template = cv2.resize(self.template_, (tw, th), interpolation=cv2.INTER_LINEAR)
        # box centres stay in the frame: no need to look further than half a box beyond it
        H, W = image.shape[:2]
        x0 = int(np.floor(max(region.x, -box_size[0])))
        y0 = int(np.floor(max(region.y, -box_size[1])))
        x1 = int(np.ceil(min(region.x + region.w, W + box_size[0])))
        y1 = int(np.ceil(min(region.y + region.h, H + box_size[1])))
        w = max(x1 - x0, int(np.ceil(box_size[0])) + 1)
        h = max(y1 - y0, int(np.ceil(box_size[1])) + 1)
        ow, oh = max(tw + 1, int(round(w * s))), max(th + 1, int(round(h * s)))
        # every k-th pixel first (still at least twice the template's resolution), then area averaging
        k = max(1, int(0.5 / s))
        view = image[::k, ::k] if k > 1 else image
        patch = cut_window(view, ((x0 + w / 2.0) / k, (y0 + h / 2.0) / k), (w / k, h / k), (ow, oh))
        grey = (patch if patch.ndim == 2 else cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)).astype(np.float32)
        ncc = cv2.matchTemplate(grey, template, cv2.TM_CCOEFF_NORMED)
        ncc = np.clip(np.nan_to_num(ncc, nan=0.0, posinf=0.0, neginf=0.0), -1.0, 1.0)
        if not colour:
            stages = {}
        elif self.colour_ and patch.ndim == 2:   # a grey frame in a colour video: no colour evidence
            stages = {"colour": np.full(ncc.shape, 0.5, np.float32)}
        else:
            if not self.colour_ and patch.ndim == 3:
                patch = cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)
            idx = colour_indices(patch, self.bins if self.colour_ else self.bins ** 2)
            stages = {"colour": box_means(self.likelihood_[idx], (tw, th))}
        step = w / float(ow)
        return ScoreMap(scores=ncc.astype(np.float32), origin=(float(x0), float(y0)), step=step,
                        box_size=(tw * step, th * step), quality=float(ncc.max()),
                        search_region=Box(float(x0), float(y0), float(w), float(h)),
                        stages=stages)


def measurement_box_size(measurement: Measurement, prior: Estimate):
    """The size of the boxes a measurement scores: a score map's ``box_size``, else the prior's size."""
    size = getattr(measurement, "box_size", None)
    return tuple(float(v) for v in (prior.box.size if size is None else size))


class VerifiedMeasurer:
    """Any measurer, with the :class:`AppearanceVerifier` map in each measurement's ``stages["verification"]``.

    The map covers the boxes whose centres lie within ``margin`` box sizes of
    the prior's centre (the box size is the measurement's when it states one,
    else the prior's), and of the measured box's centre when the measurement
    states a box.  Its ``stages["sizes"]`` holds the NCC maps of the
    same centres for boxes ``size_factors`` times that size, so a filter can
    ask whether a box of another size at its estimate looks more like the
    first frame's target (the box has the wrong size).  The measurement is
    otherwise unchanged, so a tracker's boxes do not depend on the wrapper.

    Parameters
    ----------
    inner
        The measurer to wrap.
    margin
        Reach of the map around the prior's centre, in box sizes.
    template_side, bins
        As in :class:`AppearanceVerifier`.
    size_factors
        The other box sizes matched, as factors of the measured size.
    """

    def __init__(self, inner, margin: float = 1.0, template_side: int = 16, bins: int = 8,
                 size_factors: tuple[float, ...] = (0.8, 1.25)) -> None:
        self.inner = inner
        self.margin = margin
        self.size_factors = size_factors
        self.verifier = AppearanceVerifier(template_side=template_side, bins=bins)

    def initialize(self, frame: Frame, box: Box) -> None:
        self.inner.initialize(frame, box)
        self.verifier.initialize(frame, box)

    def measure(self, frame: Frame, prior: Estimate) -> Measurement | None:
        measurement = self.inner.measure(frame, prior)
        if measurement is None:
            return None
        size = np.asarray(measurement_box_size(measurement, prior))
        # a measurement that states its box (mil's) may lie far from the prior (a re-detection), and the
        # filter's estimate lies between the two: the map covers both
        near = np.asarray(prior.box.center, float)
        box = getattr(measurement, "box", None)
        far = np.asarray(box.center, float) if isinstance(box, Box) else near
        centre, gap = (near + far) / 2.0, np.abs(far - near) / 2.0
        verification = self.verifier.verify(frame.image, self._region(centre, size, size, gap), tuple(size))
        verification.stages["sizes"] = tuple(
            self.verifier.verify(frame.image, self._region(centre, size, f * size, gap), tuple(f * size),
                                 colour=False)
            for f in self.size_factors)
        return replace(measurement, stages={**measurement.stages, "verification": verification})

    def _region(self, centre, size: np.ndarray, box_size: np.ndarray, gap=0.0) -> Box:
        """The union of the ``box_size`` boxes centred within ``margin`` sizes ``size`` (plus ``gap``) of ``centre``."""
        reach = self.margin * size + 0.5 * box_size + gap
        return Box(centre[0] - reach[0], centre[1] - reach[1], 2 * reach[0], 2 * reach[1])

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        self.inner.learn(frame, posterior)
