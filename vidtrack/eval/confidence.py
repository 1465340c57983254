"""Can a tracker's confidence and ``lost`` status be trusted?  Per-frame files and metrics.

Every evaluation run stores, beside its result file, the tracker's per-frame
confidence and status (``OUT/<filter>/<Sequence>.confidence.csv``, see
:func:`format_confidence`).  Scored against the ground truth they answer three
questions, each a pure function of per-frame arrays:

* ``false_lost``: of the frames marked ``lost``, the fraction whose box still
  overlaps the target (``IoU > 0``): false alarms;
* ``missed_loss``: of the frames marked ``tracking``, the fraction whose box
  misses the target entirely (``IoU = 0``): failures the tracker did not notice;
* ``confidence_auc``: the area under the ROC curve of the confidence as a
  predictor of ``IoU > 0.5`` (the PASCAL success criterion): 1 = the
  confidence ranks every good frame above every bad one, 0.5 = no better than
  chance (the Mann-Whitney U statistic divided by ``n_pos * n_neg``, ties
  counting one half).

* ``ece``: the expected calibration error of the confidence read as the
  probability of ``IoU > 0.5``: the frames binned by confidence into ten
  equal-width bins, ``sum_b (n_b / N) |mean confidence_b - fraction good_b|``
  (Naeini, Cooper & Hauskrecht, "Obtaining well calibrated probabilities
  using Bayesian binning", AAAI 2015); :func:`reliability` gives the bins
  themselves, the reliability diagram's points.

A metric whose denominator is empty (no ``lost`` frame, no frame of one
class) is NaN.  The init frame is not scored here: its box is given, not
tracked.

The ``measured`` column records whether the measurer returned a box on that
frame.  For the ``opencv-*`` trackers this is OpenCV's own ``ok`` flag (the
wrapper returns no measurement when ``update`` reports failure), the baseline
vidtrack's confidence is compared with (:func:`ok_flag_metrics`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DatasetError

SUFFIX = ".confidence.csv"
HEADER = "row,confidence,status,measured"
#: Keys each summary row gains (per sequence, and pooled over the frames of all sequences in ``mean``).
CONFIDENCE_KEYS = ("false_lost", "missed_loss", "confidence_auc", "ece", "lost_rate")
#: Equal-width confidence bins of the reliability diagram and the ECE.
N_BINS = 10
LOST, TRACKING = "lost", "tracking"


def confidence_path(result_path: str | Path) -> Path:
    """``OUT/<filter>/<Sequence>.confidence.csv`` beside ``OUT/<filter>/<Sequence>.txt``."""
    result_path = Path(result_path)
    return result_path.with_name(result_path.stem + SUFFIX)


def format_confidence(rows) -> str:
    """The file text of ``(row, confidence, status, measured)`` tuples, one per tracked frame.

    ``row`` is the ground-truth row (0-based) the frame belongs to.
    """
    lines = [HEADER]
    for row, confidence, status, measured in rows:
        lines.append(f"{int(row)},{float(confidence):.6g},{status},{int(bool(measured))}")
    return "\n".join(lines) + "\n"


def read_confidence(path: str | Path, n_rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a confidence file into per-ground-truth-row arrays.

    Returns
    -------
    confidence : (n_rows,) float
        NaN on rows that were not tracked.
    status : (n_rows,) str
        ``"tracking"``, ``"lost"``, or ``""`` on rows that were not tracked.
    measured : (n_rows,) bool

    Raises
    ------
    DatasetError
        When the file cannot be read or a line is malformed.
    """
    confidence = np.full(n_rows, np.nan)
    status = np.full(n_rows, "", dtype=object)
    measured = np.zeros(n_rows, dtype=bool)
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise DatasetError(f"cannot read {path}: {exc.strerror or exc}") from None
    for number, line in enumerate(lines, start=1):
        if not line.strip() or line.strip() == HEADER:
            continue
        parts = line.strip().split(",")
        try:
            row, value, flag = int(parts[0]), float(parts[1]), int(parts[3])
            state = parts[2]
        except (IndexError, ValueError):
            raise DatasetError(f"{path}, line {number}: expected 'row,confidence,status,measured'") from None
        if not 0 <= row < n_rows or state not in (LOST, TRACKING):
            raise DatasetError(f"{path}, line {number}: row {row} or status {state!r} out of range")
        confidence[row], status[row], measured[row] = value, state, bool(flag)
    return confidence, status, measured


def false_lost(ious, status) -> float:
    """Fraction of the frames marked ``lost`` whose IoU is > 0 (NaN when none is lost)."""
    ious, lost = np.asarray(ious, dtype=float), np.asarray(status) == LOST
    return float(np.mean(ious[lost] > 0)) if lost.any() else float("nan")


def missed_loss(ious, status) -> float:
    """Fraction of the frames marked ``tracking`` whose IoU is 0 (NaN when none is tracking)."""
    ious, tracking = np.asarray(ious, dtype=float), np.asarray(status) == TRACKING
    return float(np.mean(ious[tracking] <= 0)) if tracking.any() else float("nan")


def failure_spans(rows, ious, confidence, status) -> list[dict[str, float]]:
    """The runs of consecutive scored frames whose box misses the target (``IoU = 0``), and what the tracker said.

    A loss the tracker did not notice shows as a span of ``tracking`` frames
    at low confidence (the confidence knew, the ``lost`` rule did not fire) or
    at high confidence (neither knew): :func:`missed_loss` pools both.

    Parameters
    ----------
    rows
        Ground-truth row of each scored frame, increasing (unannotated rows
        between two scored frames do not break a span).
    ious, confidence, status
        Per scored frame.

    Returns
    -------
    list of dict
        One per span, in order: ``first`` and ``last`` (ground-truth rows),
        ``frames`` (scored frames in it), ``confidence`` (their mean) and
        ``lost`` (the fraction marked ``lost``).
    """
    rows = np.asarray(rows, dtype=int)
    missed = np.asarray(ious, dtype=float) <= 0
    confidence, lost = np.asarray(confidence, dtype=float), np.asarray(status) == LOST
    # a span starts at a missed frame after a hit (or the start) and ends before the next hit
    edges = np.flatnonzero(np.diff(np.concatenate([[0], missed.astype(np.int8), [0]])))
    spans = []
    for start, stop in zip(edges[::2], edges[1::2]):
        spans.append({"first": int(rows[start]), "last": int(rows[stop - 1]), "frames": int(stop - start),
                      "confidence": float(np.mean(confidence[start:stop])),
                      "lost": float(np.mean(lost[start:stop]))})
    return spans


def roc_auc(scores, labels) -> float:
    """Area under the ROC curve of ``scores`` predicting the bool ``labels``.

    ``AUC = P(s_pos > s_neg) + P(s_pos = s_neg) / 2`` over all positive/negative
    pairs, computed from mid-ranks: ``(R_pos - n_pos (n_pos + 1) / 2) / (n_pos n_neg)``
    (Mann-Whitney U).  NaN when either class is empty.
    """
    from scipy.stats import rankdata

    scores = np.asarray(scores, dtype=float).ravel()
    labels = np.asarray(labels, dtype=bool).ravel()
    n_pos = int(labels.sum())
    n_neg = labels.size - n_pos
    if n_pos == 0 or n_neg == 0:
        return float("nan")
    ranks = rankdata(scores)  # mid-ranks: ties count one half
    return float((ranks[labels].sum() - n_pos * (n_pos + 1) / 2.0) / (n_pos * n_neg))


def reliability(confidence, labels, n_bins: int = N_BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reliability diagram: per equal-width confidence bin, ``(mean confidence, fraction true, count)``.

    ``confidence`` in [0, 1] (clipped), ``labels`` bool, both ``(N,)``; NaN
    confidences are left out.  Empty bins hold NaN means and count 0.
    """
    confidence = np.asarray(confidence, dtype=float).ravel()
    labels = np.asarray(labels, dtype=bool).ravel()
    keep = np.isfinite(confidence)
    confidence, labels = np.clip(confidence[keep], 0.0, 1.0), labels[keep]
    index = np.minimum((confidence * n_bins).astype(int), n_bins - 1)
    count = np.bincount(index, minlength=n_bins).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_conf = np.bincount(index, weights=confidence, minlength=n_bins) / count
        frac = np.bincount(index, weights=labels.astype(float), minlength=n_bins) / count
    return mean_conf, frac, count.astype(int)


def expected_calibration_error(confidence, labels, n_bins: int = N_BINS) -> float:
    """``sum_b (n_b / N) |mean confidence_b - fraction true_b|`` over :func:`reliability`'s bins (NaN: no frame)."""
    mean_conf, frac, count = reliability(confidence, labels, n_bins)
    total = count.sum()
    if total == 0:
        return float("nan")
    used = count > 0
    return float(np.sum(count[used] / total * np.abs(mean_conf[used] - frac[used])))


def confidence_metrics(ious, confidence, status) -> dict[str, float]:
    """``false_lost``, ``missed_loss``, ``confidence_auc`` and ``ece`` (vs IoU > 0.5), and ``lost_rate``.

    Parameters
    ----------
    ious, confidence, status
        ``(N,)`` per scored frame: IoU with the ground truth, the tracker's
        confidence in [0, 1], its status (``"tracking"`` / ``"lost"``).
    """
    ious = np.asarray(ious, dtype=float).ravel()
    status = np.asarray(status).ravel()
    return {
        "false_lost": false_lost(ious, status),
        "missed_loss": missed_loss(ious, status),
        "confidence_auc": roc_auc(confidence, ious > 0.5),
        "ece": expected_calibration_error(confidence, ious > 0.5),
        "lost_rate": float(np.mean(status == LOST)) if status.size else float("nan"),
    }


def ok_flag_metrics(ious, measured) -> dict[str, float]:
    """:func:`confidence_metrics` of a bare ``ok`` flag: ``lost`` where not ``ok``, confidence 0/1."""
    measured = np.asarray(measured, dtype=bool).ravel()
    return confidence_metrics(ious, measured.astype(float), np.where(measured, TRACKING, LOST))


def pooled_metrics(frames, *, ok_flag: bool = False) -> dict:
    """:func:`confidence_metrics` over the frames of every sequence together.

    Pooling (rather than averaging per-sequence values) scores one confidence
    scale across all sequences, as a user thresholding it would, and keeps the
    ROC AUC defined when a sequence has frames of one class only.

    Parameters
    ----------
    frames
        ``(ious, confidence, status, measured)`` arrays, one tuple per sequence.
    ok_flag
        Also return ``ok_flag``: the same metrics for the bare ``measured``
        flag (OpenCV's ``ok`` for the ``opencv-*`` trackers).

    The result also holds ``reliability``: :func:`reliability`'s bins as
    lists ``{"confidence", "fraction", "count"}``, the reliability diagram.
    """
    frames = list(frames)
    if not frames:
        return dict.fromkeys(CONFIDENCE_KEYS, float("nan"))
    ious, confidence, status, measured = (np.concatenate([f[i] for f in frames]) for i in range(4))
    out: dict = confidence_metrics(ious, confidence, status)
    mean_conf, frac, count = reliability(confidence, ious > 0.5)
    out["reliability"] = {"confidence": [float(v) for v in mean_conf], "fraction": [float(v) for v in frac],
                          "count": [int(v) for v in count]}
    if ok_flag:
        out["ok_flag"] = ok_flag_metrics(ious, measured)
    return out
