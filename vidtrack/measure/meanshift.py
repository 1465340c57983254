"""Kernel-based mean-shift tracking (Comaniciu, Ramesh & Meer, "Kernel-Based Object Tracking", PAMI 2003).

The target is a kernel-weighted colour histogram ``q`` (Epanechnikov profile
``k(r) = 1 - r`` over the box's inscribed ellipse; eq. 21 of the paper), made
more discriminative by background weighting (section 6.1): ``q_u`` is scaled
by ``min(o*/o_u, 1)`` with ``o`` the histogram of a ring around the box.
From a start location ``y0`` each iteration computes the candidate ``p(y0)``,
the pixel weights ``w_i = sqrt(q_b(i) / p_b(i)(y0))`` (eq. 25, a histogram
back-projection) and moves to their weighted centroid (eq. 26; the
Epanechnikov kernel's ``g`` is constant), until the shift is under half a
pixel.  The similarity is the Bhattacharyya coefficient
``rho = sum_u sqrt(p_u q_u)`` (eq. 17).  Scale follows section 4.3: the best
of ``h, (1 -/+ delta) h`` by ``rho``, blended with ``gamma = 0.1``.

Grey images (all channels equal) use a 1-D intensity histogram.  Only a
window a fixed number of box sizes around the box is binned
(:func:`window_bins`), so the cost per frame follows the box, not the frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..types import Box, Estimate, Frame, PointMeasurement


def is_gray(image: np.ndarray) -> bool:
    """True when a BGR image has three identical channels (or one)."""
    if image.ndim == 2 or image.shape[2] == 1:
        return True
    step = max(1, image.shape[0] // 32)
    sample = image[::step, ::step].astype(np.int16)
    return bool(np.all(sample[..., 0] == sample[..., 1]) and np.all(sample[..., 1] == sample[..., 2]))


def bin_image(image: np.ndarray, *, gray: bool, bins: int) -> np.ndarray:
    """Histogram bin index of every pixel, ``(H, W) int32``: ``bins**3`` colour bins, or ``bins`` grey bins."""
    shift = 8 - int(np.log2(bins))
    if gray:
        channel = image if image.ndim == 2 else image[..., 0]
        return (channel >> shift).astype(np.int32)
    q = (image >> shift).astype(np.int32)
    return (q[..., 0] * bins + q[..., 1]) * bins + q[..., 2]


def window_bins(image: np.ndarray, box: Box, margin: float, *, gray: bool,
                bins: int) -> tuple[np.ndarray, tuple[int, int]]:
    """:func:`bin_image` of ``box`` grown by ``margin`` box sizes on each side (clipped to the image).

    Returns the ``(h, w) int32`` bin indices and the window's top-left pixel
    ``(x0, y0)`` in image coordinates.
    """
    H, W = image.shape[:2]
    r = Box(box.x - margin * box.w, box.y - margin * box.h, box.w * (1 + 2 * margin),
            box.h * (1 + 2 * margin)).clipped(W, H)
    x0, y0 = min(int(np.floor(r.x)), W - 1), min(int(np.floor(r.y)), H - 1)
    x1, y1 = max(int(np.ceil(r.x + r.w)), x0 + 1), max(int(np.ceil(r.y + r.h)), y0 + 1)
    return bin_image(image[y0:y1, x0:x1], gray=gray, bins=bins), (x0, y0)


def _moved(box: Box, dx: float, dy: float) -> Box:
    return Box(box.x + dx, box.y + dy, box.w, box.h)


def histogram_layout(bins: int, gray: bool) -> tuple[int, int]:
    """``(bins per channel, total bins)``: ``2 bins`` grey levels for grey images, ``bins**3`` colour cells."""
    return (bins * 2, bins * 2) if gray else (bins, bins ** 3)


def box_pixels(box: Box, width: int, height: int, origin: tuple[int, int] = (0, 0)) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)``: the pixels ``box`` touches inside the ``width x height`` image whose top-left is ``origin``."""
    ox, oy = origin
    x0, y0 = max(int(np.floor(box.x)), ox), max(int(np.floor(box.y)), oy)
    x1, y1 = min(int(np.ceil(box.x + box.w)), ox + width), min(int(np.ceil(box.y + box.h)), oy + height)
    return x0, y0, x1, y1


def kernel_histogram(bins_img: np.ndarray, box: Box, n_bins: int,
                     origin: tuple[int, int] = (0, 0)) -> tuple[np.ndarray, float]:
    """Epanechnikov-weighted, normalised histogram of ``box`` (eq. 21) and the kernel mass.

    ``bins_img`` covers the frame, or only a window of it whose top-left
    pixel is ``origin`` (frame coordinates; ``box`` stays in frame
    coordinates).  Pixels outside it are ignored; returns zeros when none
    fall inside.
    """
    H, W = bins_img.shape
    x0, y0, x1, y1 = box_pixels(box, W, H, origin)
    if x1 <= x0 or y1 <= y0:
        return np.zeros(n_bins), 0.0
    cx, cy = box.center
    ys, xs = np.mgrid[y0:y1, x0:x1]
    r2 = ((xs + 0.5 - cx) / (box.w / 2)) ** 2 + ((ys + 0.5 - cy) / (box.h / 2)) ** 2
    k = np.clip(1.0 - r2, 0.0, None)  # Epanechnikov profile
    ox, oy = origin
    hist = np.bincount(bins_img[y0 - oy:y1 - oy, x0 - ox:x1 - ox].ravel(), weights=k.ravel(), minlength=n_bins)
    mass = float(hist.sum())
    return (hist / mass if mass > 0 else hist), mass


def bhattacharyya(p: np.ndarray, q: np.ndarray) -> float:
    """Bhattacharyya coefficient ``sum sqrt(p q)`` of two normalised histograms (eq. 17)."""
    return float(np.sum(np.sqrt(p * q)))


def mean_shift(bins_img: np.ndarray, q: np.ndarray, start: Box, *, max_iter: int = 20,
               eps: float = 0.5) -> tuple[Box, float, int]:
    """Run mean-shift iterations (eqs. 25-26) from ``start``.

    Returns
    -------
    box : Box
        Converged box (same size as ``start``).
    rho : float
        Bhattacharyya coefficient at the converged box.
    iterations : int
    """
    n_bins = q.size
    H, W = bins_img.shape
    box = start
    for iteration in range(1, max_iter + 1):
        p, mass = kernel_histogram(bins_img, box, n_bins)
        if mass == 0:
            return box, 0.0, iteration
        ratio = np.sqrt(np.divide(q, p, out=np.zeros_like(q), where=p > 0))
        x0, y0 = max(int(np.floor(box.x)), 0), max(int(np.floor(box.y)), 0)
        x1, y1 = min(int(np.ceil(box.x + box.w)), W), min(int(np.ceil(box.y + box.h)), H)
        cx, cy = box.center
        ys, xs = np.mgrid[y0:y1, x0:x1]
        xs, ys = xs + 0.5, ys + 0.5
        inside = ((xs - cx) / (box.w / 2)) ** 2 + ((ys - cy) / (box.h / 2)) ** 2 <= 1.0
        w = ratio[bins_img[y0:y1, x0:x1]] * inside  # eq. 25, Epanechnikov g = const
        total = w.sum()
        if total <= 0:
            break
        nx, ny = float((w * xs).sum() / total), float((w * ys).sum() / total)  # eq. 26
        box = Box.from_center(nx, ny, box.w, box.h)
        if np.hypot(nx - cx, ny - cy) < eps:
            break
    p, _ = kernel_histogram(bins_img, box, n_bins)
    return box, bhattacharyya(p, q), iteration


def backprojection(bins_img: np.ndarray, q: np.ndarray, p: np.ndarray, region: Box) -> np.ndarray:
    """The weight image ``sqrt(q/p)`` over ``region`` ``(h, w) float32`` scaled to [0, 1] (for display)."""
    H, W = bins_img.shape
    r = region.clipped(W, H)
    x0, y0 = int(r.x), int(r.y)
    x1, y1 = int(np.ceil(r.x + r.w)), int(np.ceil(r.y + r.h))
    ratio = np.sqrt(np.divide(q, p, out=np.zeros_like(q), where=p > 0))
    img = ratio[bins_img[y0:y1, x0:x1]].astype(np.float32)
    top = float(img.max()) if img.size else 0.0
    return img / top if top > 0 else img


@dataclass
class MeanShiftMeasurer:
    """Mean-shift measurement of the box centre, starting at the filter's prediction.

    Parameters
    ----------
    bins
        Histogram bins per channel (16 -> 4096 colour bins; grey images use 2x this).
    background_weighting
        Use the background-weighted target histogram (section 6.1).
    scale_step
        Relative size change tried each frame (section 4.3); 0 (the default)
        keeps the init size: the Bhattacharyya coefficient favours shrinking
        windows, a bias the paper notes.
    scale_gamma
        Blend of the best size with the previous one.
    position_sigma
        Measurement standard deviation as a fraction of the box size at rho = 1.
    search_margin
        The iterations see the prior box grown by this many box sizes on each
        side (pixels beyond count as outside the frame).
    """

    bins: int = 16
    background_weighting: bool = True
    scale_step: float = 0.0
    scale_gamma: float = 0.1
    position_sigma: float = 0.04
    search_margin: float = 3.0

    def initialize(self, frame: Frame, box: Box) -> None:
        self.gray_ = is_gray(frame.image)
        self.channel_bins_, self.n_bins_ = histogram_layout(self.bins, self.gray_)
        bins_img, (ox, oy) = self._bins(frame, box, 1.5)   # the background ring is the box scaled by 3
        local = _moved(box, -ox, -oy)
        q, _ = kernel_histogram(bins_img, local, self.n_bins_)
        if self.background_weighting:
            q = self._background_weighted(bins_img, local, q)
        self.q_ = q
        self.size_ = box.size.copy()

    def _background_weighted(self, bins_img: np.ndarray, box: Box, q: np.ndarray) -> np.ndarray:
        ring = box.scaled(3.0)
        H, W = bins_img.shape
        r = ring.clipped(W, H)
        x0, y0, x1, y1 = int(r.x), int(r.y), int(np.ceil(r.x + r.w)), int(np.ceil(r.y + r.h))
        mask = np.ones((y1 - y0, x1 - x0), bool)
        bx0, by0 = max(int(box.x) - x0, 0), max(int(box.y) - y0, 0)
        mask[by0:by0 + int(np.ceil(box.h)), bx0:bx0 + int(np.ceil(box.w))] = False
        o = np.bincount(bins_img[y0:y1, x0:x1][mask].ravel(), minlength=self.n_bins_).astype(float)
        if o.sum() == 0:
            return q
        o /= o.sum()
        positive = o[o > 0]
        v = np.minimum(positive.min() / np.where(o > 0, o, np.inf), 1.0)
        v[o == 0] = 1.0
        weighted = q * v
        return weighted / weighted.sum() if weighted.sum() > 0 else q

    def _bins(self, frame: Frame, box: Box, margin: float) -> tuple[np.ndarray, tuple[int, int]]:
        return window_bins(frame.image, box, margin, gray=self.gray_, bins=self.channel_bins_)

    def measure(self, frame: Frame, prior: Estimate) -> PointMeasurement | None:
        cx, cy = prior.box.center
        reach = Box.from_center(cx, cy, *(self.size_ * max(1.0, 1.0 + self.scale_step)))
        bins_img, (ox, oy) = self._bins(frame, reach, self.search_margin)
        cx, cy = cx - ox, cy - oy   # window coordinates from here on
        best = None
        scales = (1.0,) if self.scale_step <= 0 else (1.0, 1.0 - self.scale_step, 1.0 + self.scale_step)
        for s in scales:
            start = Box.from_center(cx, cy, self.size_[0] * s, self.size_[1] * s)
            box, rho, _ = mean_shift(bins_img, self.q_, start)
            if best is None or rho > best[1] + 1e-9:
                best = (box, rho, s)
        box, rho, s = best
        new_size = self.scale_gamma * self.size_ * s + (1 - self.scale_gamma) * self.size_
        measured = Box.from_center(*box.center, *new_size)
        self.pending_size_ = new_size
        region = _moved(prior.box, -ox, -oy).scaled(2.0)
        p, _ = kernel_histogram(bins_img, measured, self.n_bins_)
        sigma = self.position_sigma * float(np.mean(new_size)) / max(rho, 0.05)
        measured = _moved(measured, ox, oy)
        return PointMeasurement(z=measured.center, R=np.eye(2) * sigma ** 2, box=measured, quality=rho,
                                search_region=_moved(region, ox, oy),
                                stages={"backprojection": backprojection(bins_img, self.q_, p, region)})

    def learn(self, frame: Frame, posterior: Estimate) -> None:
        # The target model is fixed (as in the paper); only the tracked size adapts.
        if posterior.status == "tracking" and hasattr(self, "pending_size_"):
            self.size_ = self.pending_size_
