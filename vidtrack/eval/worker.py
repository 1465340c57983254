"""Run each evaluation job in a fresh process.

A fresh process per job makes a result independent of the jobs that ran
before it: some OpenCV trackers (``opencv-mil``) keep random-generator state
inside the library that ``cv2.setRNGSeed`` does not reach, so in a long-lived
process their boxes would depend on the job order.  It also confines a tracker
that crashes the interpreter (a segfault in native code) to its own job.

* :func:`run_forked` (this machine): forks the job from a fork server that has
  imported vidtrack but never tracked (milliseconds per job).
* :func:`run_isolated` (daemonic processes such as Dask's default workers,
  which multiprocessing does not let have children): ``python -m
  vidtrack.eval.worker JOB OUT`` with pickle files (a
  :class:`~vidtrack.eval.jobs.Job` in, a
  :class:`~vidtrack.eval.jobs.JobOutput` out); seconds per job.
* :func:`run_fresh` picks one of the two, and runs a job whose process
  died (the OOM killer, a segfault) once more before reporting it failed.

A job's process ends when the process that started it is gone
(:func:`die_with`), so no job outlives a lost Dask worker.

When the caller stops (Ctrl-C, SIGTERM: a KeyboardInterrupt in the thread
waiting for a job) the job's process is ended with it; :func:`stop_workers`
ends every job process still running, whichever thread waits for it, so an
interrupted evaluation leaves no worker behind.

This module runs jobs (:mod:`vidtrack.eval.jobs`); the one that decides
where they run (:mod:`vidtrack.eval.running`) imports it, never the reverse.
"""

from __future__ import annotations

import os
import pickle
import select
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from .jobs import Job, JobOutput, run_job

_CONTEXT = None
#: Job processes running now (forked or child interpreters), for :func:`stop_workers`.
_RUNNING: set = set()
_RUNNING_LOCK = threading.Lock()
#: Set by :func:`stop_workers`: a job process started afterwards (by a thread already past its start) is ended.
_STOPPING = threading.Event()
#: Seconds a job process has to end after SIGTERM before it is killed.
STOP_GRACE = 5.0


def _fork_context():
    global _CONTEXT
    if _CONTEXT is None:
        import multiprocessing

        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["vidtrack.eval._preload"])
        _CONTEXT = context
    return _CONTEXT


#: Environment variable naming the PID of the process that started a child-interpreter job (see :func:`main`).
OWNER_VARIABLE = "VIDTRACK_JOB_OWNER"


def die_with(owner: int) -> None:
    """End this job process as soon as the process ``owner`` (the one waiting for its answer) is gone.

    A job's process must not outlive the process that runs it: a lost Dask
    worker's job is run again elsewhere, and an orphan would go on computing
    (and writing the same ``--rerun`` recording as the new run).  A daemon
    thread waits for ``owner`` to exit (a pidfd on Linux, else a check every
    second) and then ends this process at once.
    """
    def watch() -> None:
        try:
            handle = os.pidfd_open(owner)
        except (AttributeError, OSError):
            handle = None
        if handle is not None:
            select.select([handle], [], [])      # readable once the owner has exited
        else:
            while True:
                try:
                    os.kill(owner, 0)
                except ProcessLookupError:
                    break
                except PermissionError:
                    pass
                time.sleep(1.0)
        os._exit(1)

    if owner == os.getpid():
        return
    threading.Thread(target=watch, name="owner watch", daemon=True).start()


def _forked_child(job: Job, connection, owner: int) -> None:
    die_with(owner)   # the process that forked the job through the fork server, not the fork server
    try:
        output = run_job(job)
    except KeyboardInterrupt:
        raise SystemExit(130) from None  # a clean exit: finalizers run, nothing leaks
    connection.send(output)
    connection.close()


#: The start of a failed output's error when the job's process died (not the tracker raising).
DIED = "worker process died"
#: Times a job whose process died is run again before it is reported failed.
RETRIES = 1


def _died(job: Job, code: int | None) -> JobOutput:
    if code == 130:
        raise KeyboardInterrupt
    if code is None:
        reason = "while it was started"
    else:
        reason = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
    return JobOutput(job.filter_name, job.sequence.name, "failed", error=f"{DIED} ({reason})")


def died(output: JobOutput) -> bool:
    """Whether ``output`` is a job whose process died (the OOM killer, a segfault, a kill), not a tracker error."""
    return output.status == "failed" and (output.error or "").startswith(DIED)


def _stop(process) -> None:
    """End a job process (a multiprocessing Process or a Popen): SIGTERM, then SIGKILL after :data:`STOP_GRACE`."""
    if isinstance(process, subprocess.Popen):
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(STOP_GRACE)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        return
    if process.pid is not None and process.is_alive():
        process.terminate()
        process.join(STOP_GRACE)
        if process.is_alive():
            process.kill()
            process.join()


def stop_workers() -> None:
    """End every job process still running, and any started until :func:`allow_workers` (an interrupted
    evaluation calls it before it exits)."""
    _STOPPING.set()
    with _RUNNING_LOCK:
        running = list(_RUNNING)
    for process in running:
        _stop(process)


def allow_workers() -> None:
    """Let job processes run again after :func:`stop_workers` (an evaluation calls it when it starts)."""
    _STOPPING.clear()


def _track(process) -> None:
    with _RUNNING_LOCK:
        _RUNNING.add(process)
    if _STOPPING.is_set():
        _stop(process)


def _untrack(process) -> None:
    with _RUNNING_LOCK:
        _RUNNING.discard(process)


def run_forked(job: Job) -> JobOutput:
    """Run ``job`` (see :func:`~vidtrack.eval.jobs.run_job`) in a process forked from the fork server.

    A child that dies without an answer gives a ``failed`` output; an
    exception in the waiting thread (Ctrl-C, SIGTERM) ends the child first.
    """
    from ..sinks.base import uninterrupted

    context = _fork_context()
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_forked_child, args=(job, sender, os.getpid()), daemon=True)
    try:
        with uninterrupted():        # a signal waits till the child has its whole job
            process.start()
            _track(process)
        sender.close()
        output = receiver.recv()
    except (EOFError, BrokenPipeError):   # died before its answer, or while it was given its job
        output = None
    except BaseException:
        _stop(process)
        raise
    finally:
        sender.close()
        receiver.close()
        if process.pid is not None:
            process.join()
        _untrack(process)
    return output if output is not None else _died(job, process.exitcode)


def run_isolated(job: Job) -> JobOutput:
    """Run ``job`` (see :func:`~vidtrack.eval.jobs.run_job`) in a child interpreter.

    The child's progress bar goes to this process's stderr.  A child that
    dies without an answer gives a ``failed`` output.
    """
    from ..sinks.base import uninterrupted

    with tempfile.TemporaryDirectory(prefix="vidtrack-job-") as tmp:
        job_path, out_path = Path(tmp) / "job.pkl", Path(tmp) / "out.pkl"
        job_path.write_bytes(pickle.dumps(job))
        with uninterrupted():
            process = subprocess.Popen([sys.executable, "-m", "vidtrack.eval.worker", str(job_path),
                                        str(out_path)], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                       env={**os.environ, OWNER_VARIABLE: str(os.getpid())})
            _track(process)
        try:
            process.wait()
        except BaseException:
            _stop(process)
            raise
        finally:
            _untrack(process)
        if out_path.is_file():
            return pickle.loads(out_path.read_bytes())
    return _died(job, process.returncode)


def main(argv: list[str]) -> int:
    """``python -m vidtrack.eval.worker JOB.pkl OUT.pkl``: run the pickled job, pickle its output (exit 0)."""
    owner = os.environ.get(OWNER_VARIABLE, "")
    if owner.isdigit():
        die_with(int(owner))
    job = pickle.loads(Path(argv[0]).read_bytes())
    try:
        output = run_job(job)
    except KeyboardInterrupt:
        return 130
    tmp = argv[1] + ".part"
    Path(tmp).write_bytes(pickle.dumps(output))
    os.replace(tmp, argv[1])
    return 0


def run_fresh(job: Job) -> JobOutput:
    """:func:`run_forked` where this process may have children, else :func:`run_isolated`.

    A job whose process dies (:func:`died`) runs again, :data:`RETRIES`
    times, in a new process; then it is reported failed, saying it was
    retried.
    """
    import multiprocessing

    runner = run_isolated if multiprocessing.current_process().daemon else run_forked
    output = runner(job)
    for _ in range(RETRIES):
        if not died(output) or _STOPPING.is_set():
            return output
        output = runner(job)
    if died(output):
        output.error = f"{output.error}, also when run again"
    return output


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
