"""Small image helpers shared by the measurers: grey conversion, patch cutting, template matching.

Image functions follow scikit-image's conventions: the image first,
keyword-only options, plain ndarrays out.
"""

from __future__ import annotations

import cv2
import numba
import numpy as np


def to_gray(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3) uint8`` BGR (or already grey) -> ``(H, W) float32`` grey."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return image.astype(np.float32)


def cut_window(image: np.ndarray, centre, size, out_size: tuple[int, int]) -> np.ndarray:
    """The ``size = (w, h)`` window of ``image`` centred on ``centre``, resampled to ``out_size = (w', h')``.

    Parts outside the image repeat its border (``cv2.BORDER_REPLICATE``);
    shrinking uses area averaging (no aliasing), enlarging bilinear
    interpolation.  Works on ``(H, W)`` and ``(H, W, C)`` arrays.
    """
    w = max(int(round(size[0])), 1)
    h = max(int(round(size[1])), 1)
    x0 = int(round(centre[0] - w / 2.0))
    y0 = int(round(centre[1] - h / 2.0))
    H, W = image.shape[:2]
    cx0, cy0 = min(max(x0, 0), W - 1), min(max(y0, 0), H - 1)
    cx1, cy1 = max(min(x0 + w, W), cx0 + 1), max(min(y0 + h, H), cy0 + 1)
    patch = image[cy0:cy1, cx0:cx1]
    top, left = cy0 - y0, cx0 - x0
    bottom, right = (y0 + h) - cy1, (x0 + w) - cx1
    if top > 0 or left > 0 or bottom > 0 or right > 0:
        patch = cv2.copyMakeBorder(patch, max(top, 0), max(bottom, 0), max(left, 0), max(right, 0),
                                   cv2.BORDER_REPLICATE)
        patch = patch[max(-top, 0):patch.shape[0] - max(-bottom, 0), max(-left, 0):patch.shape[1] - max(-right, 0)]
    ow, oh = int(out_size[0]), int(out_size[1])
    if patch.shape[1] == ow and patch.shape[0] == oh:
        return np.ascontiguousarray(patch)
    shrink = patch.shape[1] * patch.shape[0] > ow * oh
    return cv2.resize(patch, (ow, oh), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


def cut_windows(image: np.ndarray, centre, sizes: np.ndarray, out_size: tuple[int, int]) -> np.ndarray:
    """:func:`cut_window` for several window sizes around one centre, in one compiled call.

    ``sizes`` ``(S, 2)`` window sizes ``(w, h)``; returns ``(S, h', w', 3)``
    uint8 for a ``(H, W, 3)`` uint8 image (``out_size = (w', h')``).  Each
    window is rounded to whole pixels as :func:`cut_window` rounds it, its
    border replicated, and resampled separably per axis: area averaging
    where the axis shrinks (OpenCV's ``INTER_AREA`` weights), linear
    interpolation between pixel centres where it grows (``INTER_LINEAR``);
    results agree with :func:`cut_window` to within rounding of the last
    grey level.  For the scale filter's ``n_scales`` windows a frame: one
    call that releases the GIL instead of ``n_scales`` resizes.
    """
    sizes = np.asarray(sizes, float)
    w = np.maximum(np.round(sizes[:, 0]), 1).astype(np.int64)
    h = np.maximum(np.round(sizes[:, 1]), 1).astype(np.int64)
    x0 = np.round(float(centre[0]) - w / 2.0).astype(np.int64)
    y0 = np.round(float(centre[1]) - h / 2.0).astype(np.int64)
    return _resample_windows(np.ascontiguousarray(image), x0, y0, w, h, int(out_size[0]), int(out_size[1]))


@numba.njit(cache=True, nogil=True)
def _axis_weights(start, length, out, limit):
    """Per output index: ``(first source index, weights)`` along one axis, source indices clamped to ``[0, limit)``.

    Area weights (OpenCV's ``INTER_AREA``) when ``length >= out``, else
    linear interpolation between pixel centres (``INTER_LINEAR``).
    """
    scale = length / out
    if scale >= 1.0:
        span = int(np.ceil(scale)) + 1
    else:
        span = 2
    index = np.zeros((out, span), np.int64)
    weight = np.zeros((out, span))
    for d in range(out):
        if scale >= 1.0:
            f1 = d * scale
            f2 = min(f1 + scale, float(length))
            cell = f2 - f1
            k = 0
            i = int(np.floor(f1))
            while i < f2 and k < span:
                lo = max(f1, float(i))
                hi = min(f2, float(i + 1))
                if hi > lo:
                    index[d, k] = min(max(start + i, 0), limit - 1)
                    weight[d, k] = (hi - lo) / cell
                    k += 1
                i += 1
        else:
            f = (d + 0.5) * scale - 0.5
            i = int(np.floor(f))
            t = f - i
            if i < 0:
                i, t = 0, 0.0
            if i >= length - 1:
                i, t = length - 1, 0.0
            index[d, 0] = min(max(start + i, 0), limit - 1)
            index[d, 1] = min(max(start + min(i + 1, length - 1), 0), limit - 1)
            weight[d, 0] = 1.0 - t
            weight[d, 1] = t
    return index, weight


@numba.njit(cache=True, nogil=True)
def _resample_windows(image, x0, y0, w, h, out_w, out_h):
    H, W, C = image.shape
    S = x0.shape[0]
    out = np.empty((S, out_h, out_w, C), np.uint8)
    row = np.empty((out_w, C))
    for s in range(S):
        xi, xw = _axis_weights(x0[s], w[s], out_w, W)
        yi, yw = _axis_weights(y0[s], h[s], out_h, H)
        for dy in range(out_h):
            for dx in range(out_w):
                acc0 = 0.0
                acc1 = 0.0
                acc2 = 0.0
                for a in range(yi.shape[1]):
                    wy = yw[dy, a]
                    if wy == 0.0:
                        continue
                    r = yi[dy, a]
                    for b in range(xi.shape[1]):
                        wgt = wy * xw[dx, b]
                        if wgt == 0.0:
                            continue
                        c = xi[dx, b]
                        acc0 += wgt * image[r, c, 0]
                        acc1 += wgt * image[r, c, 1]
                        acc2 += wgt * image[r, c, 2]
                out[s, dy, dx, 0] = min(max(int(np.rint(acc0)), 0), 255)
                out[s, dy, dx, 1] = min(max(int(np.rint(acc1)), 0), 255)
                out[s, dy, dx, 2] = min(max(int(np.rint(acc2)), 0), 255)
    return out


def cut_patch(grey: np.ndarray, centre: np.ndarray, size: tuple[int, int]) -> np.ndarray | None:
    """The ``(h, w) = size[::-1]`` patch of ``grey`` centred on ``centre`` (None when it leaves the image)."""
    tw, th = size
    x0, y0 = int(round(centre[0] - tw / 2.0)), int(round(centre[1] - th / 2.0))
    if x0 < 0 or y0 < 0 or x0 + tw > grey.shape[1] or y0 + th > grey.shape[0]:
        return None
    return grey[y0:y0 + th, x0:x0 + tw].copy()


def match_templates(grey: np.ndarray, templates, centre: np.ndarray, radius: np.ndarray, *,
                    motion_weight: float = 0.0, combine: str = "max"):
    """Normalised cross-correlation peak of ``templates`` near ``centre`` (the centre refinement).

    The response is the element-wise maximum (``combine="max"``) or mean
    (``"mean"``) over the templates of
    ``cv2.matchTemplate(..., TM_CCOEFF_NORMED)`` in a window of
    ``radius`` pixels around ``centre`` (both region pixels), minus
    ``motion_weight`` times the squared displacement from ``centre`` in
    template-size units; the peak is refined to sub-pixel by a parabola.

    Returns
    -------
    (centre ``(2,)``, peak NCC in [-1, 1]) or None when the window is smaller than the template.
    """
    th, tw = templates[0].shape
    h, w = grey.shape
    x0 = max(int(np.floor(centre[0] - tw / 2.0 - radius[0])), 0)
    y0 = max(int(np.floor(centre[1] - th / 2.0 - radius[1])), 0)
    x1 = min(int(np.ceil(centre[0] + tw / 2.0 + radius[0])), w)
    y1 = min(int(np.ceil(centre[1] + th / 2.0 + radius[1])), h)
    if x1 - x0 < tw + 1 or y1 - y0 < th + 1:
        return None
    window = grey[y0:y1, x0:x1]
    resp = None
    for t in templates:
        r = cv2.matchTemplate(window, t, cv2.TM_CCOEFF_NORMED)
        resp = r if resp is None else (np.maximum(resp, r) if combine == "max" else resp + r)
    if combine != "max":
        resp = resp / len(templates)
    rh, rw = resp.shape
    us = (np.arange(rw) + x0 + tw / 2.0 - centre[0]) / tw
    vs = (np.arange(rh) + y0 + th / 2.0 - centre[1]) / th
    objective = resp - motion_weight * (vs[:, None] ** 2 + us[None, :] ** 2)
    v, u = np.unravel_index(int(np.argmax(objective)), objective.shape)
    du = dv = 0.0
    if 0 < u < rw - 1:
        a, b, c = objective[v, u - 1], objective[v, u], objective[v, u + 1]
        den = a - 2 * b + c
        du = 0.5 * (a - c) / den if den < 0 else 0.0
    if 0 < v < rh - 1:
        a, b, c = objective[v - 1, u], objective[v, u], objective[v + 1, u]
        den = a - 2 * b + c
        dv = 0.5 * (a - c) / den if den < 0 else 0.0
    found = np.array([x0 + u + du + tw / 2.0, y0 + v + dv + th / 2.0])
    return found, float(resp[v, u])


# Load the compiled kernels at import, not inside the first tracked frame (see vidtrack.measure.slic).
cut_windows(np.zeros((8, 8, 3), np.uint8), (4.0, 4.0), np.array([[4.0, 4.0], [2.0, 2.0]]), (3, 3))
