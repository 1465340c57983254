"""Tracking metrics: pure functions of box arrays that never modify their inputs.

Boxes are ``(N, 4)`` arrays of ``x, y, w, h`` in one shared convention (a
1-pixel shift of both arrays changes nothing).  The definitions follow
Wu, Lim, Yang, "Online Object Tracking: A Benchmark" (CVPR 2013) for the
success (AUC) and precision plots, and the PASCAL VOC overlap criterion used
by the PROST (Santner et al., CVPR 2010) and MIL (Babenko et al., CVPR 2009)
papers:

* IoU of continuous boxes: ``|A ∩ B| / |A ∪ B|`` (OTB's ``calcRectInt`` with
  its ``+1``/``-1`` pixel terms is the same number);
* success AUC: mean over thresholds ``t = 0, 0.05, ..., 1`` of the fraction of
  frames with ``IoU > t``;
* precision@20: fraction of frames with centre error ``<= 20`` px;
* PASCAL score: fraction of frames with ``IoU > 0.5``;
* centre error: Euclidean distance of box centres, mean in px;
* normalised precision (Fan et al., "LaSOT: A High-quality Benchmark for
  Large-scale Single Object Tracking", CVPR 2019; also TrackingNet's): the
  centre error with each axis divided by the ground-truth box's size (at least
  1 px), and the area under its precision curve over thresholds
  ``0, 0.01, ..., 0.5``, i.e. the mean of the curve;
* GOT-10k (Huang, Zhao, Huang, "GOT-10k: A Large High-Diversity Benchmark
  for Generic Object Tracking in the Wild", TPAMI 2021): average overlap
  ``AO`` = mean IoU, success rates ``SR0.5`` and ``SR0.75`` = fractions of
  frames with ``IoU > 0.5`` / ``> 0.75``, over the frames after the first
  where the target is present, both boxes clipped to the frame; the overall
  figures pool the frames of every sequence.

The success and precision curves use each benchmark's own threshold grid
(:data:`SUCCESS_GRIDS`): OTB, LaSOT and UAV123 ``0, 0.05, ..., 1``; GOT-10k
``0, 0.01, ..., 1``.

Only the frames selected by ``mask`` (by default the annotated ground-truth
rows, see :func:`~vidtrack.eval.datasets.annotated_rows`) are scored.
"""

from __future__ import annotations

import numpy as np

from .datasets import annotated_rows

#: OTB success-plot thresholds 0, 0.05, ..., 1 (21 values).
SUCCESS_THRESHOLDS = np.linspace(0.0, 1.0, 21)
#: OTB precision-plot thresholds 0 .. 50 px.
PRECISION_THRESHOLDS = np.arange(0, 51, dtype=float)
#: LaSOT's normalised-precision thresholds 0, 0.01, ..., 0.5 (51 values).
NORM_PRECISION_THRESHOLDS = np.linspace(0.0, 0.5, 51)
#: Success-plot thresholds of each benchmark layout (OTB's for the others).
SUCCESS_GRIDS = {"got10k": np.linspace(0.0, 1.0, 101)}
METRIC_NAMES = ("auc", "precision20", "pascal", "center_error", "norm_precision")
#: GOT-10k's metrics, on the sequences of that layout.
GOT10K_METRICS = ("ao", "sr50", "sr75")


def _as_boxes(boxes) -> np.ndarray:
    # np.array copies: nothing below can write into the caller's array
    return np.array(boxes, dtype=float).reshape(-1, 4)


def iou(boxes_a, boxes_b) -> np.ndarray:
    """Row-wise intersection over union of two ``(N, 4)`` box arrays -> ``(N,)``.

    Rows with a non-finite value or a non-positive size give 0.
    """
    a, b = _as_boxes(boxes_a), _as_boxes(boxes_b)
    if a.shape != b.shape:
        raise ValueError(f"box arrays differ in shape: {a.shape} vs {b.shape}")
    with np.errstate(invalid="ignore"):
        # |A ∩ B| = max(0, min(x2) - max(x1)) * max(0, min(y2) - max(y1))
        iw = np.minimum(a[:, 0] + a[:, 2], b[:, 0] + b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
        ih = np.minimum(a[:, 1] + a[:, 3], b[:, 1] + b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
        inter = np.clip(iw, 0.0, None) * np.clip(ih, 0.0, None)
        union = a[:, 2] * a[:, 3] + b[:, 2] * b[:, 3] - inter
        out = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
    valid = annotated_rows(a) & annotated_rows(b)
    return np.where(valid & np.isfinite(out), out, 0.0)


def center_error(boxes_a, boxes_b) -> np.ndarray:
    """Row-wise distance between box centres ``(x + w/2, y + h/2)`` -> ``(N,)`` px.

    Rows with a non-finite value give ``inf`` (a failure at every threshold).
    """
    a, b = _as_boxes(boxes_a), _as_boxes(boxes_b)
    if a.shape != b.shape:
        raise ValueError(f"box arrays differ in shape: {a.shape} vs {b.shape}")
    ca = a[:, :2] + a[:, 2:] / 2.0
    cb = b[:, :2] + b[:, 2:] / 2.0
    distance = np.hypot(ca[:, 0] - cb[:, 0], ca[:, 1] - cb[:, 1])
    return np.where(np.isfinite(distance), distance, np.inf)


def normalized_center_error(results, ground_truth) -> np.ndarray:
    """Row-wise centre distance with each axis divided by the ground truth's ``w`` / ``h`` (at least 1) -> ``(N,)``.

    ``sqrt(((cx_r - cx_g) / max(1, w_g))^2 + ((cy_r - cy_g) / max(1, h_g))^2)``;
    rows with a non-finite value give ``inf``.
    """
    a, b = _as_boxes(results), _as_boxes(ground_truth)
    if a.shape != b.shape:
        raise ValueError(f"box arrays differ in shape: {a.shape} vs {b.shape}")
    offset = (a[:, :2] + a[:, 2:] / 2.0) - (b[:, :2] + b[:, 2:] / 2.0)
    with np.errstate(invalid="ignore"):
        distance = np.hypot(*(offset / np.maximum(b[:, 2:], 1.0)).T)
    return np.where(np.isfinite(distance), distance, np.inf)


def normalized_precision(norm_errors) -> float:
    """Mean over ``0, 0.01, ..., 0.5`` of the fraction of frames with normalised error ``<= t`` (LaSOT)."""
    return float(np.mean(precision_curve(norm_errors, NORM_PRECISION_THRESHOLDS)))


def clip_to_frame(boxes, width: float, height: float) -> np.ndarray:
    """Boxes cut to the frame ``[0, width] x [0, height]`` (0-based pixels): a new ``(N, 4)`` array."""
    boxes = _as_boxes(boxes)
    boxes[:, 0] = np.clip(boxes[:, 0], 0.0, width)
    boxes[:, 1] = np.clip(boxes[:, 1], 0.0, height)
    boxes[:, 2] = np.clip(boxes[:, 2], 0.0, width - boxes[:, 0])
    boxes[:, 3] = np.clip(boxes[:, 3], 0.0, height - boxes[:, 1])
    return boxes


def got10k_scores(ious) -> dict[str, float]:
    """GOT-10k's ``ao`` (mean IoU), ``sr50`` and ``sr75`` (fractions with IoU > 0.5, > 0.75); NaN with no frame."""
    ious = np.asarray(ious, dtype=float).ravel()
    if ious.size == 0:
        return dict.fromkeys(GOT10K_METRICS, float("nan"))
    return {"ao": float(np.mean(ious)), "sr50": float(np.mean(ious > 0.5)), "sr75": float(np.mean(ious > 0.75))}


def recentred(boxes, centres_from) -> np.ndarray:
    """The boxes of ``boxes``, each moved to the centre of the same row of ``centres_from`` (sizes kept).

    Scoring a tracker's result recentred on the ground truth (a perfect centre
    with the tracker's size), or the ground truth recentred on the result (the
    tracker's centre with a perfect size), tells how much of its loss of
    success AUC comes from the centre and how much from the size.
    """
    boxes, centres_from = _as_boxes(boxes), _as_boxes(centres_from)
    if boxes.shape != centres_from.shape:
        raise ValueError(f"{len(boxes)} boxes for {len(centres_from)} centres")
    out = boxes.copy()
    out[:, :2] = centres_from[:, :2] + 0.5 * (centres_from[:, 2:] - boxes[:, 2:])
    return out


def fixed_size(ground_truth) -> bool:
    """Whether every annotated row of ``ground_truth`` has one width and one height.

    Such ground truth (the original MIL sequences: one box size for the whole
    sequence) scores any size change the tracker makes as an error, even one
    the target made.
    """
    truth = _as_boxes(ground_truth)
    sizes = truth[annotated_rows(truth), 2:]
    return bool(len(sizes) and np.all(sizes == sizes[0]))


def success_curve(ious, thresholds=SUCCESS_THRESHOLDS) -> np.ndarray:
    """Fraction of frames with ``IoU > t`` for each threshold ``t`` (OTB success plot)."""
    ious = np.asarray(ious, dtype=float).ravel()
    thresholds = np.asarray(thresholds, dtype=float)
    if ious.size == 0:
        return np.full(thresholds.shape, np.nan)
    return (ious[None, :] > thresholds[:, None]).mean(axis=1)


def precision_curve(errors, thresholds=PRECISION_THRESHOLDS) -> np.ndarray:
    """Fraction of frames with centre error ``<= t`` for each ``t`` px (OTB precision plot)."""
    errors = np.asarray(errors, dtype=float).ravel()
    thresholds = np.asarray(thresholds, dtype=float)
    if errors.size == 0:
        return np.full(thresholds.shape, np.nan)
    return (errors[None, :] <= thresholds[:, None]).mean(axis=1)


def success_auc(ious) -> float:
    """OTB success AUC: mean of :func:`success_curve` over ``0, 0.05, ..., 1``."""
    return float(np.mean(success_curve(ious)))


def precision_at(errors, threshold: float = 20.0) -> float:
    """Fraction of frames with centre error ``<= threshold`` px."""
    return float(precision_curve(errors, [threshold])[0])


def pascal_score(ious, threshold: float = 0.5) -> float:
    """Fraction of frames with ``IoU > threshold`` (PASCAL VOC criterion)."""
    return float(success_curve(ious, [threshold])[0])


def frame_scores(results, ground_truth, mask=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per scored frame ``(ious, centre_errors, normalised_centre_errors)``.

    Parameters
    ----------
    results, ground_truth
        ``(N, 4)`` box arrays, same convention, row ``i`` = frame ``i``.
    mask
        ``(N,)`` bool of the frames to score; always intersected with the
        annotated ground-truth rows.
    """
    results, ground_truth = _as_boxes(results), _as_boxes(ground_truth)
    if results.shape != ground_truth.shape:
        raise ValueError(f"{len(results)} result rows for {len(ground_truth)} ground-truth rows")
    keep = annotated_rows(ground_truth)
    if mask is not None:
        keep = keep & np.asarray(mask, dtype=bool).ravel()
    kept, truth = results[keep], ground_truth[keep]
    return iou(kept, truth), center_error(kept, truth), normalized_center_error(kept, truth)


def score(results, ground_truth, mask=None) -> dict[str, float]:
    """``auc``, ``precision20``, ``pascal``, ``center_error``, ``norm_precision`` and ``frames`` (count scored).

    See :func:`frame_scores` for the arguments and :func:`summarize` for the metrics.
    """
    return summarize(*frame_scores(results, ground_truth, mask))


def summarize(ious: np.ndarray, errors: np.ndarray, norm_errors: np.ndarray | None = None) -> dict[str, float]:
    """The metrics of :func:`score` from per-frame ``(ious, centre_errors, normalised errors)``; NaN with no frame."""
    if ious.size == 0:
        return {**dict.fromkeys(METRIC_NAMES, float("nan")), "frames": 0}
    return {
        "auc": success_auc(ious),
        "precision20": precision_at(errors, 20.0),
        "pascal": pascal_score(ious, 0.5),
        "center_error": float(np.mean(errors)),
        "norm_precision": float("nan") if norm_errors is None else normalized_precision(norm_errors),
        "frames": int(ious.size),
    }
