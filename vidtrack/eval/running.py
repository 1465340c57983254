"""Running an evaluation's jobs: reusing earlier results, then here, in local processes or on Dask.

Every job is seeded and, by default, runs in a fresh interpreter
(:mod:`vidtrack.eval.worker`), so the result files are the same whether the
jobs ran one after another, ``workers`` at a time or on a Dask cluster
(``scheduler``); only the measured fps differ.  On a multi-machine cluster the
dataset path must be readable by the workers (the result files are written by
the caller, so the output folder need not be shared; ``--rerun`` recordings
are written by the workers).
"""

from __future__ import annotations

from contextlib import closing
from pathlib import Path
from typing import Any, Callable, Iterator

from ..errors import UsageError
from .jobs import Job, JobOutput, effective_settings, run_job
from .results import RECORD_VERSION, read_record, write_result


def reusable(out: Path, job: Job, settings: dict[str, str] | None = None) -> dict | None:
    """The record of an earlier run of ``job`` whose result file can be reused, else None.

    It must be complete and made the same way: the same record version,
    tracker, sequence, seed, tracked rows and effective settings
    (``settings``: :func:`~vidtrack.eval.jobs.effective_settings` of the job,
    computed here when not given).
    """
    record = read_record(out, *job.key)
    if record is None:
        return None
    if settings is None:
        settings = effective_settings(job.filter_name, job.settings)
    expected = {"version": RECORD_VERSION, "filter": job.filter_name, "sequence": job.sequence.name,
                "seed": job.seed, "rows": len(job.sequence), "tracked": list(job.tracked_rows()),
                "settings": settings}
    if any(record.get(k) != v for k, v in expected.items()):
        return None
    if job.rerun_path is not None and not Path(job.rerun_path).is_file():
        return None
    return record


def execute(jobs: list[Job], *, workers: int = 1, scheduler: str | None = None,
            isolate: bool = True) -> Iterator[JobOutput]:
    """Run ``jobs`` and yield their outputs as they finish.

    ``scheduler`` (a Dask scheduler address) sends them to a Dask cluster;
    else ``workers`` jobs run at once on this machine.  With ``isolate``
    (the default, required unless the jobs run one at a time here) every job
    runs in a fresh process (:mod:`vidtrack.eval.worker`),
    so its result does not depend on which jobs ran before it in the same
    process; a job whose process dies is run once more, then yielded as
    ``failed`` (:func:`~vidtrack.eval.worker.run_fresh`).  When the
    caller stops early (an exception such as Ctrl-C or SIGTERM, or closing
    this generator), every job process still running is ended.
    """
    if not jobs:
        return
    if not isolate and (scheduler is not None or workers > 1):
        raise UsageError("jobs run in this process only one at a time (no --jobs or --scheduler)")
    from .worker import allow_workers, run_fresh, stop_workers

    allow_workers()
    runner = run_fresh if isolate else run_job
    try:
        if scheduler is not None:
            yield from _execute_dask(jobs, scheduler, runner)
        elif workers > 1 and len(jobs) > 1:
            yield from _execute_threads(jobs, workers, runner)
        else:
            for job in jobs:
                yield runner(job)
    except BaseException:
        stop_workers()   # no job process outlives an interrupted evaluation
        raise


def _failed(job: Job, exc: BaseException) -> JobOutput:
    from .worker import DIED

    if type(exc).__name__ == "KilledWorker":   # Dask gave up: every worker that took the job was lost
        tries = getattr(exc, "allowed_failures", None)
        where = "on every Dask worker that ran it" if tries is None else f"on the {tries + 1} Dask workers that ran it"
        return JobOutput(job.filter_name, job.sequence.name, "failed", error=f"{DIED} ({where})")
    return JobOutput(job.filter_name, job.sequence.name, "failed", error=f"{type(exc).__name__}: {exc}")


def _execute_threads(jobs: list[Job], workers: int, runner) -> Iterator[JobOutput]:
    from concurrent.futures import ThreadPoolExecutor, as_completed

    # each thread waits on its own worker process: ``workers`` jobs track in parallel
    from .worker import stop_workers

    pool = ThreadPoolExecutor(max_workers=min(workers, len(jobs)))
    try:
        futures = {pool.submit(runner, job): job for job in jobs}
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as exc:
                yield _failed(futures[future], exc)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)   # no new job starts ...
        stop_workers()                                    # ... and the running ones end: the threads return
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _execute_dask(jobs: list[Job], scheduler: str, runner) -> Iterator[JobOutput]:
    """Run ``jobs`` on the Dask cluster at ``scheduler``, yielding their outputs as they finish.

    A worker lost in the middle of a job (killed, out of memory, its machine
    gone) costs only that attempt: the scheduler gives the job to another
    worker (``distributed.scheduler.allowed-failures`` times, 3 by default),
    and a job whose every worker was lost is yielded as ``failed``
    (:data:`~vidtrack.eval.worker.DIED`); every other job's output is
    yielded as usual.
    """
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


def run_jobs(jobs: list[Job], out: str | Path, *, force: bool = False, workers: int = 1,
             scheduler: str | None = None, isolate: bool = True,
             on_output: Callable[[JobOutput], Any] | None = None) -> dict[tuple[str, str], JobOutput]:
    """Run every job whose result ``out`` does not already hold, writing each result as it finishes.

    Returns every job's output by ``(filter, sequence)``: ``done`` (run now,
    written), ``reused`` (its record) or ``failed`` (its error; nothing
    written).  ``force`` re-runs every job; ``workers``, ``scheduler`` and
    ``isolate`` as for :func:`execute`; ``on_output`` is called with each
    output as it arrives, reused ones included.
    """
    out = Path(out)
    settings: dict[tuple[str, str], dict[str, str]] = {}  # effective settings, once per tracker and settings
    outputs: dict[tuple[str, str], JobOutput] = {}
    pending = []
    for job in jobs:
        key = (job.filter_name, repr(job.settings))
        if key not in settings:
            settings[key] = effective_settings(job.filter_name, job.settings)
        record = None if force else reusable(out, job, settings[key])
        if record is None:
            pending.append(job)
            continue
        outputs[job.key] = JobOutput(*job.key, "reused", record=record)
        if on_output is not None:
            on_output(outputs[job.key])
    # closing: an interruption while a result is written still ends the running jobs' processes
    with closing(execute(pending, workers=workers, scheduler=scheduler, isolate=isolate)) as finished:
        for output in finished:
            if output.status != "failed":
                write_result(out, output.filter_name, output.sequence_name, output.lines or [], output.record,
                             output.confidence)
            outputs[(output.filter_name, output.sequence_name)] = output
            if on_output is not None:
                on_output(output)
    return outputs
