"""One evaluation job: one tracker, with its settings, on one benchmark sequence.

A job runs anywhere (this process, a fresh local process, a Dask worker: see
:mod:`vidtrack.eval.running`): it reads the frames, tracks, and returns the
result lines and a small record (fps, frames, seed, effective settings ...);
the calling process writes them (:mod:`vidtrack.eval.results`).  Everything a
job needs travels inside it, so it pickles: the sequence, the seed, the
settings and the progress bar factory (a module-level callable, pickled by
reference).
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import cv2

from ..errors import DatasetError
from ..sinks.files import format_box
from ..types import Box, Frame, TrackState
from ..version import __version__
from . import confidence as conf
from .datasets import BenchmarkSequence
from .frame_times import FrameTimer
from .results import NOT_TRACKED, RECORD_VERSION


@dataclass(frozen=True)
class Job:
    """One tracker on one sequence (picklable, so it can run in another process).

    ``settings`` are the tracker's options as ``(dotted key, value)`` pairs,
    applied in order (:func:`vidtrack.api.tracker_config`); ``progress``, when
    given, is called as ``progress(total=N, desc=TEXT)`` and returns a bar
    with ``update(n)`` and ``close()`` (the command line's progress bar).
    """

    filter_name: str
    sequence: BenchmarkSequence
    seed: int = 0
    max_frames: int | None = None
    rerun_path: str | None = None
    settings: tuple[tuple[str, Any], ...] = ()
    progress: Callable[..., Any] | None = None

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


def effective_settings(filter_name: str, settings: tuple[tuple[str, Any], ...] | dict[str, Any] = ()) -> dict:
    """Every option of the tracker's configuration with ``settings`` applied, as ``{dotted key: text}``.

    The run record keeps it, so a result is reused only for the same
    configuration (whether an option was set or left at its default).

    Raises
    ------
    UsageError
        For an option the tracker does not take or a bad value.
    """
    from ..api import tracker_config
    from ..config import describe

    config = tracker_config(filter_name, dict(settings))
    return {} if config is None else {key: value for key, value, _, _ in describe(config)}


class _Collector:
    """A sink keeping every state's box (0-based pixels), confidence, status and measured flag."""

    def __init__(self) -> None:
        self.boxes: list[Box] = []
        self.states: list[tuple[float, str, bool]] = []

    def write(self, frame: Frame, targets: Mapping[int, TrackState]) -> None:
        state = targets[1]   # one target per job
        self.boxes.append(state.box)
        self.states.append((state.confidence, state.status, state.measured is not None))

    def close(self) -> None:
        pass


class _NoBar:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _ground_truth_pixels(sequence: BenchmarkSequence, start: int, stop: int) -> dict[int, Box]:
    """Annotated rows in ``[start, stop)`` keyed by the source's frame index, 0-based pixels."""
    annotated = sequence.annotated
    return {row - start: sequence.to_pixels(sequence.ground_truth_box(row))
            for row in range(start, stop) if annotated[row]}


def track_job(job: Job) -> JobOutput:
    """Run ``job`` and return its result lines and record (raises on a tracker error).

    A frame in the middle that does not decode is predicted through; the
    record then lists it under ``skipped`` (ground-truth row and reason).
    """
    from ..recipes import build_tracker
    from ..run import run_tracker
    from ..sources import ImageFolderSource

    sequence = job.sequence
    start, stop = job.tracked_rows()
    # OpenCV's trackers (opencv-mil samples patches) draw from OpenCV's per-thread global RNG:
    # reset it so a job's result does not depend on which jobs ran before it in this process
    cv2.setRNGSeed(job.seed)
    settings = dict(job.settings)
    tracker = FrameTimer(build_tracker(job.filter_name, seed=job.seed, settings=settings))  # each frame's seconds
    source = ImageFolderSource(sequence.path, files=list(sequence.files[start:stop]))
    init_box = sequence.to_pixels(sequence.ground_truth_box(start))
    collector = _Collector()
    sinks: list[Any] = [collector]
    if job.rerun_path is not None:
        from ..sinks.rerun import RerunSink  # lazily: eval works without rerun

        Path(job.rerun_path).parent.mkdir(parents=True, exist_ok=True)
        sinks.append(RerunSink(job.rerun_path, filter_name=job.filter_name,
                               ground_truth=_ground_truth_pixels(sequence, start, stop)))
    bar = _NoBar() if job.progress is None else job.progress(total=stop - start,
                                                              desc=f"{job.filter_name} {sequence.name}")
    try:
        result = run_tracker(tracker, source, init_box, sinks, on_frame=lambda frame, targets: bar.update(1))
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
        "vidtrack": __version__,
        "filter": job.filter_name,
        "sequence": sequence.name,
        "seed": job.seed,
        "settings": effective_settings(job.filter_name, settings),
        "max_frames": job.max_frames,
        "rows": len(sequence),
        "tracked": [start, stop],
        "origin": sequence.origin,
        "frames": result.frames,
        "lost_frames": result.lost_frames,
        "track_seconds": result.track_seconds,
        "fps": result.fps,
        "frame_seconds": tracker.per_frame(result.frames),  # the tracker's seconds per tracked row, in order
        "rerun": job.rerun_path,
    }
    if result.skipped:  # frames that did not decode: the tracker predicted through them (rows 0-based)
        record["skipped"] = [{"row": start + s.index, "reason": s.reason} for s in result.skipped]
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
