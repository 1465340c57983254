"""An evaluation: run trackers over benchmark sequences into result files, then score the files.

One *job* is one tracker on one sequence (:mod:`vidtrack.eval.jobs`); the
jobs run, or earlier results are reused (:mod:`vidtrack.eval.running`); the
result files (:mod:`vidtrack.eval.results`) are then scored by pure functions
(:mod:`vidtrack.eval.scoring`).  :func:`run_evaluation` does the three in
turn; ``vidtrack eval`` is its command line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from .datasets import BenchmarkSequence
from .jobs import Job, JobOutput
from .running import run_jobs
from .scoring import failed_row, score_results


@dataclass
class Evaluation:
    """Everything an evaluation produced.

    ``summary`` is ``{filter: {sequence: {auc, precision20, pascal,
    center_error, fps}, ..., "mean": {...}}}`` (failed sequences, and those
    that could not be read, have ``None`` metrics and an ``error``: the
    reason); ``curves`` maps ``(filter,
    sequence)`` to ``(success, precision)`` curves; ``status`` maps it to
    ``done``, ``reused`` or ``failed``; ``records`` maps each pair that did
    not fail to its run record.
    """

    summary: dict[str, dict[str, dict[str, Any]]]
    curves: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    status: dict[tuple[str, str], str]
    records: dict[tuple[str, str], dict[str, Any]] = field(default_factory=dict)


def make_jobs(sequences: list[BenchmarkSequence], filters: list[str], *, seed: int = 0,
              max_frames: int | None = None, settings: Mapping[str, Any] | None = None,
              rerun_dir: str | Path | None = None, progress: Callable[..., Any] | None = None) -> list[Job]:
    """One job per sequence and filter; options as for :func:`run_evaluation`.

    Each sequence's filters run back to back, so the trackers compared in one
    run (their fps above all) meet the same load of a shared machine.
    """
    jobs = []
    pairs = tuple((settings or {}).items())
    for sequence in sequences:
        for name in filters:
            rerun_path = None if rerun_dir is None else str(Path(rerun_dir).resolve() / name / f"{sequence.name}.rrd")
            jobs.append(Job(name, sequence, seed=seed, max_frames=max_frames, rerun_path=rerun_path, settings=pairs,
                            progress=progress))
    return jobs


def run_evaluation(sequences: list[BenchmarkSequence], filters: list[str], out: str | Path, *,
                   seed: int = 0, max_frames: int | None = None, settings: Mapping[str, Any] | None = None,
                   force: bool = False, workers: int = 1, scheduler: str | None = None, isolate: bool = True,
                   rerun_dir: str | Path | None = None, progress: Callable[..., Any] | None = None,
                   on_output: Callable[[JobOutput], None] | None = None,
                   unreadable: Mapping[str, str] | None = None) -> Evaluation:
    """Run every filter on every sequence (reusing earlier results) and score the result files.

    Parameters
    ----------
    sequences, filters
        What to run; every pair is one job.
    out
        Output folder (``OUT/<filter>/<Sequence>.txt`` and ``.json``).
    seed, max_frames
        Tracker seed; at most this many frames tracked per sequence (testing).
    settings
        Tracker options by dotted key, applied to every filter
        (:func:`vidtrack.api.tracker_config`); the run records keep the
        effective settings, so results made with other settings are not reused.
    force
        Re-run even when a matching result exists.
    workers, scheduler, isolate
        Jobs at once on this machine, or a Dask scheduler address; a fresh
        process per job (see :func:`vidtrack.eval.running.execute`).
    rerun_dir
        Also write ``RERUN_DIR/<filter>/<Sequence>.rrd`` recordings.
    progress
        A progress bar factory for each job, called as
        ``progress(total=N, desc=TEXT)`` (a picklable, module-level callable);
        None: no progress bars.
    on_output
        Called with each job's output as it finishes (reused ones included).
    unreadable
        ``{sequence name: reason}`` of the dataset's sequences that could not
        be read (:class:`~vidtrack.eval.datasets.DatasetReading`): each is a
        failed row of every filter in the summary, with its reason.
    """
    jobs = make_jobs(sequences, filters, seed=seed, max_frames=max_frames, settings=settings, rerun_dir=rerun_dir,
                     progress=progress)
    outputs = run_jobs(jobs, out, force=force, workers=workers, scheduler=scheduler, isolate=isolate,
                       on_output=on_output)
    records = {key: output.record for key, output in outputs.items() if output.status != "failed"}
    errors = {key: output.error or "failed" for key, output in outputs.items() if output.status == "failed"}
    summary, curves = score_results(sequences, filters, out, records, errors)
    summary = with_unreadable(summary, unreadable or {})
    return Evaluation(summary, curves, {key: output.status for key, output in outputs.items()}, records)


def with_unreadable(summary: dict[str, dict[str, dict[str, Any]]], unreadable: Mapping[str, str]
                    ) -> dict[str, dict[str, dict[str, Any]]]:
    """``summary`` with a failed row (no metrics, ``error``: the reason) per unreadable sequence and filter.

    The rows come after the scored sequences and before ``mean``, whose
    ``failed`` list names them too; the mean of the metrics is unchanged.
    """
    if not unreadable:
        return summary
    result = {}
    for name, rows in summary.items():
        rows = {sequence: row for sequence, row in rows.items() if sequence != "mean"}
        rows.update((sequence, failed_row(reason)) for sequence, reason in unreadable.items() if sequence not in rows)
        mean = dict(summary[name].get("mean", {}))
        mean["failed"] = [*mean.get("failed", []), *(s for s in unreadable if s not in mean.get("failed", []))]
        result[name] = {**rows, "mean": mean}
    return result
