"""DSST's scale filter: a 1-D correlation filter over scales (Danelljan et al., sec. 3.2).

Danelljan, Häger, Khan & Felsberg, "Accurate Scale Estimation for Robust
Visual Tracking" (BMVC 2014): once the translation filter has located the
target, a separate filter estimates its scale change.  Its sample is the
target resampled at ``S`` scales ``a^k`` to one model size, each scale's
features flattened into one row; the filter is DSST's eqs. 4-6
(:mod:`vidtrack.measure.dcf`) with the Fourier transform taken along the
scale axis, trained towards a Gaussian peaked at ``k = 0``, so the best
``k`` of a new sample is the scale change.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import fft

from ..types import Box
from .dcf import running_average
from .features import cell_features
from .image import cut_window


@dataclass
class ScaleFilter:
    """DSST's separate 1-D scale filter (Danelljan et al., sec. 3.1-3.2).

    ``n_scales`` patches of the target box times ``step ** k`` (``k`` from
    ``-n_scales // 2`` to ``n_scales // 2``) are resampled to a fixed model
    size of about ``model_area`` pixels; their cell features (computed in
    one pass over the patches stacked into one image, so gradients and
    block normalisation see their neighbour at the seams), flattened and
    weighted by a Hann window over the scales, are the ``(S, D)`` sample.  A
    1-D correlation filter along the scale axis (the same eqs. 4-6 with the
    Fourier transform over scales) is trained towards a Gaussian peaked at
    ``k = 0``; the best ``k`` of a new sample is the scale change.  The
    sample is real, so the transforms over scales are real ones (``rfft``:
    the half spectrum, the other half being its conjugate).

    Parameters
    ----------
    n_scales, step
        Number of scales and the ratio between neighbours.
    model_area
        Pixels of the resampled patch.
    learning_rate, lam
        ``eta`` and ``lambda``.
    sigma_factor
        Width of the desired response over scales (DSST's ``1/4``, times ``n_scales / sqrt(33)``).
    cell, colour
        Cell side of the features in resampled pixels, and the Lab colour channels beside HOG
        (:func:`~vidtrack.measure.features.cell_features`).
    """

    n_scales: int = 17
    step: float = 1.02
    model_area: float = 512.0
    learning_rate: float = 0.025
    lam: float = 1e-2
    sigma_factor: float = 0.25
    cell: int = 4
    colour: bool = True

    def initialize(self, image: np.ndarray, box: Box) -> None:
        f = np.sqrt(self.model_area / max(box.area, 1.0))
        self.model_size_ = tuple(int(max(round(v * f / self.cell), 2) * self.cell) for v in box.size)
        self.exponents_ = np.arange(self.n_scales) - self.n_scales // 2
        self.factors_ = self.step ** self.exponents_.astype(float)
        sigma = self.n_scales / np.sqrt(33.0) * self.sigma_factor
        self.target_fft_ = fft.rfft(np.exp(-0.5 * self.exponents_ ** 2 / sigma ** 2)).astype(np.complex64)
        self.window_ = np.hanning(self.n_scales + 2)[1:-1].astype(np.float32)
        self.numerator_ = self.denominator_ = None
        self.last_sample_fft_ = None
        self.update(image, box, rate=1.0)

    def sample(self, image: np.ndarray, centre, size) -> np.ndarray:
        """The ``(S, D)`` multi-scale sample around ``centre`` for a box of ``size``.

        One window of whole image pixels, covering the largest scale, is cut
        and resampled (:func:`~vidtrack.measure.image.cut_window`) to the
        smallest scale's resolution; the ``S`` patches are then interpolated
        from it (bilinear, ``cv2.remap``) at their exact sub-pixel extents, so
        that scales 2 % apart differ even on a target a few pixels wide.  The
        patches are stacked into one image for a single feature pass
        (gradients and block normalisation see the neighbouring patch at the
        seams).
        """
        model = np.array(self.model_size_, float)
        centre = np.asarray(centre, float)
        density = model / (np.asarray(size, float) * self.factors_[0])     # model pixels per image pixel
        half = 0.5 * np.asarray(size, float) * self.factors_[-1]             # the largest scale's half extent
        low, high = np.floor(centre - half) - 1.0, np.ceil(centre + half) + 1.0
        out = np.maximum(np.round((high - low) * density), 2.0).astype(int)
        window = cut_window(image, 0.5 * (low + high), high - low, (int(out[0]), int(out[1])))
        actual = out / (high - low)                                         # window pixels per image pixel
        mw, mh = self.model_size_
        offsets = [(np.arange(n) + 0.5 - n / 2.0) / density[axis] for axis, n in enumerate((mw, mh))]
        relative = (self.factors_ / self.factors_[0])[:, None, None]
        map_x = (centre[0] + offsets[0][None, None, :] * relative - low[0]) * actual[0] - 0.5
        map_y = (centre[1] + offsets[1][None, :, None] * relative - low[1]) * actual[1] - 0.5
        shape = (self.n_scales, mh, mw)
        stacked = cv2.remap(window, np.broadcast_to(map_x, shape).reshape(-1, mw).astype(np.float32),
                            np.broadcast_to(map_y, shape).reshape(-1, mw).astype(np.float32),
                            cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        features = cell_features(stacked, cell=self.cell, colour=self.colour)
        return features.reshape(self.n_scales, -1) * self.window_[:, None]

    def update(self, image: np.ndarray, box: Box, *, rate: float | None = None) -> None:
        """Learn from the multi-scale sample around ``box``: the one :meth:`estimate` took, when it has one.

        Reusing the estimate's sample (taken at the detected centre, before
        the scale change) saves the ``n_scales`` resamplings of a second
        sample; it is off the posterior box by at most one scale step.
        """
        rate = self.learning_rate if rate is None else rate
        f = self.last_sample_fft_
        self.last_sample_fft_ = None
        if f is None:
            f = fft.rfft(self.sample(image, box.center, box.size), axis=0)
        num = np.conj(self.target_fft_)[:, None] * f              # conj(G) F_l
        den = np.sum(f.real ** 2 + f.imag ** 2, axis=1)            # sum_l |F_l|^2
        self.numerator_, self.denominator_ = running_average((self.numerator_, self.denominator_), (num, den), rate)

    def estimate(self, image: np.ndarray, centre, size) -> float:
        """The scale change of the target around ``centre``: the factor of the best-responding scale."""
        z = fft.rfft(self.sample(image, centre, size), axis=0)
        self.last_sample_fft_ = z
        response = fft.irfft(np.sum(np.conj(self.numerator_) * z, axis=1) / (self.denominator_ + self.lam),
                             n=self.n_scales)
        k = int(np.argmax(response))
        exponent = float(self.exponents_[k])
        if 0 < k < len(response) - 1:   # sub-step: the parabola through the peak and its neighbours
            a, b, c = response[k - 1], response[k], response[k + 1]
            den = a - 2.0 * b + c
            if den < 0:
                exponent += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
        return float(self.step ** exponent)
