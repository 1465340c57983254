"""Run trackers over benchmark sequences into result files, then score the files.

One *job* = one tracker on one sequence.  A job runs anywhere (this process,
a local worker process, a Dask worker): it reads the frames, tracks, and
returns the result lines and a small record (fps, frames, seed ...).  The
calling process writes them, atomically, as::

    OUT/<filter>/<Sequence>.txt     one x,y,w,h line per ground-truth row, in the
                                    sequence's own convention; rows not tracked
                                    (outside the MIL frames range, before the init
                                    frame, past --max-frames) are 0,0,0,0
    OUT/<filter>/<Sequence>.json    the run record (fps of *that* run, tracked rows,
                                    seed, max_frames), so a resumed evaluation
                                    reports honest fps and reuses only matching runs
    OUT/<filter>/<Sequence>.confidence.csv  the tracker's per-frame confidence and
                                    status (:mod:`vidtrack.eval.confidence`)

Scoring reads only these files (DESIGN.md: evaluation goes through files).
Every job is seeded and, by default, runs in a fresh interpreter
(:mod:`vidtrack.eval.worker`), so the files are the same whether the jobs ran
one after another, ``workers`` at a time or on a Dask cluster (``scheduler``);
only the measured fps differ.  On a multi-machine cluster the
dataset path must be readable by the workers (the result files are written by
the caller, so the output folder need not be shared; ``--rerun`` recordings are
written by the workers).
"""

from __future__ import annotations

import json
import math
import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

import cv2
import numpy as np

from ..errors import DatasetError, OutputError, UsageError
from ..types import Box, Frame, TrackState
from .datasets import BenchmarkSequence, read_boxes
from ..sinks.files import format_box
from . import confidence as conf
from .metrics import PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS, METRIC_NAMES, frame_scores, summarize, \
    iou, precision_curve, success_curve

RECORD_VERSION = 1
NOT_TRACKED = "0,0,0,0"


@dataclass(frozen=True)
class Job:
    """One tracker on one sequence (picklable, so it can run in another process)."""

    filter_name: str
    sequence: BenchmarkSequence
    seed: int = 0
    max_frames: int | None = None
    rerun_path: str | None = None
    quiet: bool = True

    @property
    def key(self) -> tuple[str, str]:
        return self.filter_name, self.sequence.name

    def tracked_rows(self) -> tuple[int, int]:
        """``(start, stop)`` ground-truth rows this job tracks."""
        start, stop = self.sequence.eval_range
        if self.max_frames is not None:
            stop = min(stop, start + self.max_frames)
        return start, stop


@dataclass
class JobOutput:
    """What a job returned: ``status`` is ``done``, ``reused`` or ``failed``."""

    filter_name: str
    sequence_name: str
    status: str
    lines: list[str] | None = None
    record: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    confidence: str | None = None  # the per-frame confidence file's text


class _Collector:
    """A sink keeping every state's box (0-based pixels), confidence, status and measured flag."""

    def __init__(self) -> None:
        self.boxes: list[Box] = []
        self.states: list[tuple[float, str, bool]] = []

    def write(self, frame: Frame, state: TrackState) -> None:
        self.boxes.append(state.box)
        self.states.append((state.confidence, state.status, state.measured is not None))

    def close(self) -> None:
        pass


def _ground_truth_pixels(sequence: BenchmarkSequence, start: int, stop: int) -> dict[int, Box]:
    """Annotated rows in ``[start, stop)`` keyed by the source's frame index, 0-based pixels."""
    annotated = sequence.annotated
    return {row - start: sequence.to_pixels(sequence.ground_truth_box(row))
            for row in range(start, stop) if annotated[row]}


def track_job(job: Job) -> JobOutput:
    """Run ``job`` and return its result lines and record (raises on a tracker error)."""
    from ..cli import progress_bar
    from ..run import run_tracker
    from ..sources import ImageFolderSource
    from ..recipes import build_tracker

    sequence = job.sequence
    start, stop = job.tracked_rows()
    # OpenCV's trackers (opencv-mil samples patches) draw from OpenCV's per-thread global RNG:
    # reset it so a job's result does not depend on which jobs ran before it in this process
    cv2.setRNGSeed(job.seed)
    tracker = build_tracker(job.filter_name, seed=job.seed)
    source = ImageFolderSource(sequence.path, files=list(sequence.files[start:stop]))
    init_box = sequence.to_pixels(sequence.ground_truth_box(start))
    collector = _Collector()
    sinks: list[Any] = [collector]
    if job.rerun_path is not None:
        from ..sinks.rerun import RerunSink  # lazily: eval works without rerun

        Path(job.rerun_path).parent.mkdir(parents=True, exist_ok=True)
        sinks.append(RerunSink(job.rerun_path, filter_name=job.filter_name,
                               ground_truth=_ground_truth_pixels(sequence, start, stop)))
    bar = progress_bar(total=stop - start, desc=f"{job.filter_name} {sequence.name}", quiet=job.quiet)
    try:
        result = run_tracker(tracker, source, init_box, sinks, on_state=lambda state: bar.update(1))
    finally:
        bar.close()
    if result.interrupted:
        raise KeyboardInterrupt
    if result.decode_error:
        raise DatasetError(f"sequence {sequence.name}: {result.decode_error}")
    if result.frames != stop - start:
        raise DatasetError(f"sequence {sequence.name}: tracked {result.frames} of {stop - start} frames")
    lines = [NOT_TRACKED] * len(sequence)
    for row, box in enumerate(collector.boxes, start=start):
        lines[row] = format_box(sequence.from_pixels(box), 3)
    record = {
        "version": RECORD_VERSION,
        "filter": job.filter_name,
        "sequence": sequence.name,
        "seed": job.seed,
        "max_frames": job.max_frames,
        "rows": len(sequence),
        "tracked": [start, stop],
        "origin": sequence.origin,
        "frames": result.frames,
        "lost_frames": result.lost_frames,
        "track_seconds": result.track_seconds,
        "fps": result.fps,
        "rerun": job.rerun_path,
    }
    confidence = conf.format_confidence((row, *s) for row, s in enumerate(collector.states, start=start))
    return JobOutput(job.filter_name, sequence.name, "done", lines, record, confidence=confidence)


def run_job(job: Job) -> JobOutput:
    """:func:`track_job`, with any tracker error turned into a ``failed`` output."""
    try:
        return track_job(job)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # a crashing tracker fails this job only
        message = f"{type(exc).__name__}: {exc}".strip()
        return JobOutput(job.filter_name, job.sequence.name, "failed", error=message.splitlines()[0],
                         record={"traceback": traceback.format_exc()})


# ---------------------------------------------------------------- files


def result_paths(out: Path, filter_name: str, sequence_name: str) -> tuple[Path, Path]:
    """``(OUT/<filter>/<Sequence>.txt, OUT/<filter>/<Sequence>.json)``."""
    folder = Path(out) / filter_name
    return folder / f"{sequence_name}.txt", folder / f"{sequence_name}.json"


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def write_output(out: Path, output: JobOutput) -> None:
    """Write a finished job's result file, then its record (the record marks it complete)."""
    txt, record = result_paths(out, output.filter_name, output.sequence_name)
    _write_atomic(txt, "\n".join(output.lines) + "\n")
    if output.confidence is not None:
        _write_atomic(conf.confidence_path(txt), output.confidence)
    _write_atomic(record, json.dumps(output.record, indent=1) + "\n")


def reusable(out: Path, job: Job) -> dict | None:
    """The record of an earlier run of ``job`` whose result file can be reused, else None."""
    txt, record_path = result_paths(out, *job.key)
    if not (txt.is_file() and record_path.is_file() and conf.confidence_path(txt).is_file()):
        return None
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    expected = {"version": RECORD_VERSION, "filter": job.filter_name, "sequence": job.sequence.name,
                "seed": job.seed, "rows": len(job.sequence), "tracked": list(job.tracked_rows())}
    if any(record.get(k) != v for k, v in expected.items()):
        return None
    if job.rerun_path is not None and not Path(job.rerun_path).is_file():
        return None
    return record


# ---------------------------------------------------------------- execution


def execute(jobs: list[Job], *, workers: int = 1, scheduler: str | None = None,
            isolate: bool = True) -> Iterator[JobOutput]:
    """Run ``jobs`` and yield their outputs as they finish.

    ``scheduler`` (a Dask scheduler address) sends them to a Dask cluster;
    else ``workers`` jobs run at once on this machine.  With ``isolate``
    (the default, required unless the jobs run one at a time here) every job
    runs in a fresh process (:mod:`vidtrack.eval.worker`),
    so its result does not depend on which jobs ran before it in the same
    process; a job whose process dies is yielded as ``failed``.
    """
    if not jobs:
        return
    if not isolate and (scheduler is not None or workers > 1):
        raise UsageError("jobs run in this process only one at a time (no --jobs or --scheduler)")
    from .worker import run_fresh

    runner = run_fresh if isolate else run_job
    if scheduler is not None:
        yield from _execute_dask(jobs, scheduler, runner)
    elif workers > 1 and len(jobs) > 1:
        yield from _execute_threads(jobs, workers, runner)
    else:
        for job in jobs:
            yield runner(job)


def _failed(job: Job, exc: BaseException) -> JobOutput:
    return JobOutput(job.filter_name, job.sequence.name, "failed", error=f"{type(exc).__name__}: {exc}")


def _execute_threads(jobs: list[Job], workers: int, runner) -> Iterator[JobOutput]:
    from concurrent.futures import ThreadPoolExecutor, as_completed

    # each thread waits on its own worker process: ``workers`` jobs track in parallel
    pool = ThreadPoolExecutor(max_workers=min(workers, len(jobs)))
    try:
        futures = {pool.submit(runner, job): job for job in jobs}
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as exc:
                yield _failed(futures[future], exc)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _execute_dask(jobs: list[Job], scheduler: str, runner) -> Iterator[JobOutput]:
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise UsageError("--scheduler needs dask[distributed] installed") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise UsageError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
    try:
        futures = {client.submit(runner, job, pure=False): job for job in jobs}
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as exc:  # the worker died or could not run the job
                yield _failed(futures[future], exc)
    finally:
        client.close()


# ---------------------------------------------------------------- scoring


@dataclass
class SequenceScore:
    """Scores of one result file: metrics dict and the curves for the plots."""

    metrics: dict[str, Any]
    success: np.ndarray | None = None
    precision: np.ndarray | None = None
    frames: tuple[np.ndarray, ...] | None = None  # (ious, confidence, status, measured) for the confidence metrics


def score_result(sequence: BenchmarkSequence, result_path: Path, record: dict | None) -> SequenceScore:
    """Score one result file against its sequence (fps from the record of its run).

    The scored frames are the annotated ground-truth rows the run tracked
    (``record["tracked"]``; without a record, the sequence's evaluated range).
    """
    results = read_boxes(result_path)
    if len(results) != len(sequence):
        raise DatasetError(f"{result_path}: {len(results)} rows for {len(sequence)} ground-truth rows")
    start, stop = record["tracked"] if record else sequence.eval_range
    mask = np.zeros(len(sequence), dtype=bool)
    mask[start:stop] = True
    ious, errors = frame_scores(results, sequence.ground_truth, mask)
    metrics = summarize(ious, errors)
    fps = float(record["fps"]) if record and record.get("fps") is not None else float("nan")
    row = {name: metrics[name] for name in METRIC_NAMES}
    row["fps"] = fps
    frames = None
    row.update(dict.fromkeys(conf.CONFIDENCE_KEYS, float("nan")))
    if conf.confidence_path(result_path).is_file():
        keep = sequence.annotated & mask
        keep[start] = False  # the init box is given, not tracked
        confidence, status, measured = conf.read_confidence(conf.confidence_path(result_path), len(sequence))
        frames = (iou(results[keep], sequence.ground_truth[keep]), confidence[keep], status[keep], measured[keep])
        row.update(conf.confidence_metrics(*frames[:3]))
    return SequenceScore(row, success_curve(ious, SUCCESS_THRESHOLDS), precision_curve(errors, PRECISION_THRESHOLDS),
                         frames)


def _failed_row(error: str) -> dict[str, Any]:
    return {**{name: None for name in (*METRIC_NAMES, "fps")}, "error": error}


def mean_row(rows: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Mean over the sequences that did not fail; ``failed`` lists the others."""
    ok = [r for r in rows.values() if "error" not in r]
    mean: dict[str, Any] = {}
    for name in (*METRIC_NAMES, "fps"):
        values = [r[name] for r in ok if r[name] is not None and math.isfinite(r[name])]
        mean[name] = float(np.mean(values)) if values else None
    failed = [seq for seq, r in rows.items() if "error" in r]
    if failed:
        mean["failed"] = failed
    return mean


@dataclass
class Evaluation:
    """Everything an evaluation produced.

    ``summary`` is ``{filter: {sequence: {auc, precision20, pascal,
    center_error, fps}, ..., "mean": {...}}}`` (failed sequences have
    ``None`` metrics and an ``error``); ``curves`` maps ``(filter,
    sequence)`` to ``(success, precision)`` curves; ``status`` maps it to
    ``done``, ``reused`` or ``failed``.
    """

    summary: dict[str, dict[str, dict[str, Any]]]
    curves: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    status: dict[tuple[str, str], str]


def run_evaluation(sequences: list[BenchmarkSequence], filters: list[str], out: str | Path, *,
                   seed: int = 0, max_frames: int | None = None, force: bool = False, workers: int = 1,
                   scheduler: str | None = None, isolate: bool = True, rerun_dir: str | Path | None = None,
                   quiet: bool = True, on_output: Callable[[JobOutput], None] | None = None) -> Evaluation:
    """Run every filter on every sequence (reusing earlier results) and score the result files.

    Parameters
    ----------
    sequences, filters
        What to run; every pair is one job.
    out
        Output folder (``OUT/<filter>/<Sequence>.txt`` and ``.json``).
    seed, max_frames
        Tracker seed; at most this many frames tracked per sequence (testing).
    force
        Re-run even when a matching result exists.
    workers, scheduler, isolate
        Jobs at once on this machine, or a Dask scheduler address; a fresh
        process per job (see :func:`execute`).
    rerun_dir
        Also write ``RERUN_DIR/<filter>/<Sequence>.rrd`` recordings.
    quiet
        No progress bars.
    on_output
        Called with each job's output as it finishes (reused ones included).
    """
    out = Path(out)
    jobs = []
    for name in filters:
        for sequence in sequences:
            rerun_path = None if rerun_dir is None else str(Path(rerun_dir).resolve() / name / f"{sequence.name}.rrd")
            jobs.append(Job(name, sequence, seed=seed, max_frames=max_frames, rerun_path=rerun_path, quiet=quiet))

    records: dict[tuple[str, str], dict] = {}
    status: dict[tuple[str, str], str] = {}
    errors: dict[tuple[str, str], str] = {}
    pending = []
    for job in jobs:
        record = None if force else reusable(out, job)
        if record is None:
            pending.append(job)
        else:
            records[job.key], status[job.key] = record, "reused"
            if on_output is not None:
                on_output(JobOutput(*job.key, "reused", record=record))
    for output in execute(pending, workers=workers, scheduler=scheduler, isolate=isolate):
        key = (output.filter_name, output.sequence_name)
        status[key] = output.status
        if output.status == "failed":
            errors[key] = output.error or "failed"
        else:
            write_output(out, output)
            records[key] = output.record
        if on_output is not None:
            on_output(output)

    summary: dict[str, dict[str, dict[str, Any]]] = {}
    curves: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
    for name in filters:
        rows: dict[str, dict[str, Any]] = {}
        pooled = []
        for sequence in sequences:
            key = (name, sequence.name)
            if key in errors:
                rows[sequence.name] = _failed_row(errors[key])
                continue
            scored = score_result(sequence, result_paths(out, *key)[0], records[key])
            rows[sequence.name] = scored.metrics
            curves[key] = (scored.success, scored.precision)
            if scored.frames is not None:
                pooled.append(scored.frames)
        rows["mean"] = mean_row(rows)
        rows["mean"].update(conf.pooled_metrics(pooled, ok_flag=name.startswith("opencv-")))
        summary[name] = rows
    return Evaluation(summary, curves, status)
