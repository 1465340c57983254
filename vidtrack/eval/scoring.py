"""Scoring an evaluation: pure functions from result files to the summary table and the curves.

Nothing here runs a tracker: the inputs are the sequences (their ground
truth), the result files an evaluation wrote (:mod:`vidtrack.eval.results`)
and their run records; the output is the summary ``{filter: {sequence:
{metric: value}, "mean": {...}}}`` and the success / precision curves of
every result.  The metrics are those of :mod:`vidtrack.eval.metrics` (OTB
success AUC, precision@20, PASCAL, centre error) and
:mod:`vidtrack.eval.confidence` (whether the confidence and the ``lost``
status can be trusted).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import DatasetError
from . import confidence as conf
from .datasets import BenchmarkSequence, read_boxes
from .metrics import (METRIC_NAMES, PRECISION_THRESHOLDS, SUCCESS_GRIDS, SUCCESS_THRESHOLDS, clip_to_frame,
                      frame_scores, got10k_scores, iou, precision_curve, recentred, score, success_curve,
                      summarize)
from .results import result_paths

Curves = dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
Summary = dict[str, dict[str, dict[str, Any]]]


@dataclass
class SequenceScore:
    """Scores of one result file: metrics dict and the curves for the plots."""

    metrics: dict[str, Any]
    success: np.ndarray | None = None
    precision: np.ndarray | None = None
    frames: tuple[np.ndarray, ...] | None = None  # (ious, confidence, status, measured) for the confidence metrics
    got10k_ious: np.ndarray | None = None  # the frames GOT-10k scores, pooled into the overall AO and SR
    rows: np.ndarray | None = None  # the ground-truth row of each of ``frames``


def got10k_frames(sequence: BenchmarkSequence, results: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """IoUs of the frames GOT-10k scores: after the init frame, target present, boxes clipped to the frame.

    Present means ``cover.label`` > 0 where the sequence has one (the GOT-10k
    toolkit's rule), else not marked absent.
    """
    keep = mask & sequence.annotated
    keep[sequence.init_index] = False
    hidden = sequence.occluded if sequence.occluded is not None else sequence.absent
    if hidden is not None:
        keep &= ~hidden
    a, b = results[keep], sequence.ground_truth[keep]
    if sequence.frame_size is not None:
        width, height = sequence.frame_size
        a, b = clip_to_frame(a, width, height), clip_to_frame(b, width, height)
    return iou(a, b)


def read_result(sequence: BenchmarkSequence, result_path: Path) -> np.ndarray:
    """The ``(N, 4)`` boxes of one result file, one row per ground-truth row of ``sequence``.

    Raises
    ------
    DatasetError
        When the file has another number of rows.
    """
    results = read_boxes(result_path)
    if len(results) != len(sequence):
        raise DatasetError(f"{result_path}: {len(results)} rows for {len(sequence)} ground-truth rows")
    return results


def tracked_rows(sequence: BenchmarkSequence, record: Mapping[str, Any] | None) -> tuple[int, np.ndarray]:
    """The first ground-truth row the run tracked (its init row) and the ``(N,)`` bool mask of all it tracked.

    The range is the run record's ``tracked``; without a record, the sequence's evaluated range.
    """
    start, stop = record["tracked"] if record else sequence.eval_range
    mask = np.zeros(len(sequence), dtype=bool)
    mask[start:stop] = True
    return int(start), mask


def score_result(sequence: BenchmarkSequence, result_path: Path, record: Mapping[str, Any] | None) -> SequenceScore:
    """Score one result file against its sequence (fps from the record of its run).

    The scored frames are the annotated ground-truth rows the run tracked
    (``record["tracked"]``; without a record, the sequence's evaluated range).
    """
    results = read_result(sequence, result_path)
    start, mask = tracked_rows(sequence, record)
    ious, errors, norm_errors = frame_scores(results, sequence.ground_truth, mask)
    metrics = summarize(ious, errors, norm_errors)
    fps = float(record["fps"]) if record and record.get("fps") is not None else float("nan")
    row = {name: metrics[name] for name in METRIC_NAMES}
    got_ious = None
    if sequence.layout == "got10k":
        got_ious = got10k_frames(sequence, results, mask)
        row.update(got10k_scores(got_ious))
    row["fps"] = fps
    frames = rows = None
    row.update(dict.fromkeys(conf.CONFIDENCE_KEYS, float("nan")))
    if conf.confidence_path(result_path).is_file():
        keep = sequence.annotated & mask
        keep[start] = False  # the init box is given, not tracked
        confidence, status, measured = conf.read_confidence(conf.confidence_path(result_path), len(sequence))
        frames = (iou(results[keep], sequence.ground_truth[keep]), confidence[keep], status[keep], measured[keep])
        rows = np.flatnonzero(keep)
        row.update(conf.confidence_metrics(*frames[:3]))
    grid = SUCCESS_GRIDS.get(sequence.layout, SUCCESS_THRESHOLDS)
    return SequenceScore(row, success_curve(ious, grid), precision_curve(errors, PRECISION_THRESHOLDS), frames,
                         got_ious, rows)


def centre_and_size_aucs(sequence: BenchmarkSequence, results: np.ndarray, mask: np.ndarray
                         ) -> tuple[float, float, float]:
    """Success AUC of ``results``, of its centres with the ground truth's sizes, and of its sizes at the true centres.

    The first is the summary's ``auc``; the second is what the run would
    score with a perfect size, the third with a perfect centre
    (:func:`~vidtrack.eval.metrics.recentred`).  The frames are those
    :func:`score_result` scores (``mask``: the rows the run tracked).
    """
    truth = sequence.ground_truth
    as_run, true_size, true_centre = (score(boxes, truth, mask)["auc"]
                                      for boxes in (results, recentred(truth, results), recentred(results, truth)))
    return as_run, true_size, true_centre


def failed_row(error: str) -> dict[str, Any]:
    """The summary row of a run that failed: no metrics, its ``error``."""
    return {**{name: None for name in (*METRIC_NAMES, "fps")}, "error": error}


def mean_row(rows: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Mean over the sequences that did not fail; ``failed`` lists the others."""
    ok = [r for r in rows.values() if "error" not in r]
    mean: dict[str, Any] = {}
    for name in (*METRIC_NAMES, "fps"):
        values = [r[name] for r in ok if r.get(name) is not None and math.isfinite(r[name])]
        mean[name] = float(np.mean(values)) if values else None
    failed = [seq for seq, r in rows.items() if "error" in r]
    if failed:
        mean["failed"] = failed
    return mean


def score_results(sequences: Sequence[BenchmarkSequence], filters: Sequence[str], out: str | Path,
                  records: Mapping[tuple[str, str], Mapping[str, Any] | None],
                  errors: Mapping[tuple[str, str], str] | None = None) -> tuple[Summary, Curves]:
    """The summary and the curves of the result files in ``out``.

    Parameters
    ----------
    sequences, filters
        What was evaluated: every ``(filter, sequence)`` pair.
    out
        The evaluation folder (``OUT/<filter>/<Sequence>.txt``).
    records
        The run record of each pair (its fps and tracked rows).
    errors
        Pairs whose run failed, with the error: a row without metrics.

    Returns
    -------
    summary
        ``{filter: {sequence: {auc, precision20, pascal, center_error,
        norm_precision, fps, false_lost, missed_loss, confidence_auc,
        lost_rate}, ..., "mean": {...}}}``, and ``ao``, ``sr50``, ``sr75`` on
        GOT-10k sequences; the mean row pools the confidence metrics and
        GOT-10k's over the frames of every sequence.
    curves
        ``(filter, sequence) -> (success, precision)`` curves.
    """
    errors = errors or {}
    summary: Summary = {}
    curves: Curves = {}
    for name in filters:
        rows: dict[str, dict[str, Any]] = {}
        pooled = []
        got_ious = []
        for sequence in sequences:
            key = (name, sequence.name)
            if key in errors:
                rows[sequence.name] = failed_row(errors[key])
                continue
            scored = score_result(sequence, result_paths(out, *key)[0], records.get(key))
            rows[sequence.name] = scored.metrics
            curves[key] = (scored.success, scored.precision)
            if scored.frames is not None:
                pooled.append(scored.frames)
            if scored.got10k_ious is not None:
                got_ious.append(scored.got10k_ious)
        rows["mean"] = mean_row(rows)
        if got_ious:  # GOT-10k's overall figures pool the frames of every sequence
            rows["mean"].update(got10k_scores(np.concatenate(got_ious)))
        rows["mean"].update(conf.pooled_metrics(pooled, ok_flag=name.startswith("opencv-")))
        summary[name] = rows
    return summary, curves
