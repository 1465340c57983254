"""Small image helpers shared by the measurers: grey conversion, patch cutting, template matching.

Image functions follow scikit-image's conventions: the image first,
keyword-only options, plain ndarrays out.
"""

from __future__ import annotations

import cv2
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
