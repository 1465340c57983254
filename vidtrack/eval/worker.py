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
* :func:`run_fresh` picks one of the two.

This module runs jobs (:mod:`vidtrack.eval.jobs`); the one that decides
where they run (:mod:`vidtrack.eval.running`) imports it, never the reverse.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

from .jobs import Job, JobOutput, run_job

_CONTEXT = None


def _fork_context():
    global _CONTEXT
    if _CONTEXT is None:
        import multiprocessing

        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["vidtrack.eval._preload"])
        _CONTEXT = context
    return _CONTEXT


def _forked_child(job: Job, connection) -> None:
    try:
        output = run_job(job)
    except KeyboardInterrupt:
        raise SystemExit(130) from None  # a clean exit: finalizers run, nothing leaks
    connection.send(output)
    connection.close()


def _died(job: Job, code: int | None) -> JobOutput:
    if code == 130:
        raise KeyboardInterrupt
    reason = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
    return JobOutput(job.filter_name, job.sequence.name, "failed", error=f"worker process died ({reason})")


def run_forked(job: Job) -> JobOutput:
    """Run ``job`` (see :func:`~vidtrack.eval.jobs.run_job`) in a process forked from the fork server.

    A child that dies without an answer gives a ``failed`` output.
    """
    context = _fork_context()
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_forked_child, args=(job, sender), daemon=True)
    process.start()
    sender.close()
    try:
        output = receiver.recv()
    except EOFError:
        output = None
    finally:
        receiver.close()
        process.join()
    return output if output is not None else _died(job, process.exitcode)


def run_isolated(job: Job) -> JobOutput:
    """Run ``job`` (see :func:`~vidtrack.eval.jobs.run_job`) in a child interpreter.

    The child's progress bar goes to this process's stderr.  A child that
    dies without an answer gives a ``failed`` output.
    """
    with tempfile.TemporaryDirectory(prefix="vidtrack-job-") as tmp:
        job_path, out_path = Path(tmp) / "job.pkl", Path(tmp) / "out.pkl"
        job_path.write_bytes(pickle.dumps(job))
        completed = subprocess.run([sys.executable, "-m", "vidtrack.eval.worker", str(job_path), str(out_path)],
                                   stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, check=False)
        if out_path.is_file():
            return pickle.loads(out_path.read_bytes())
    return _died(job, completed.returncode)


def main(argv: list[str]) -> int:
    """``python -m vidtrack.eval.worker JOB.pkl OUT.pkl``: run the pickled job, pickle its output (exit 0)."""
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
    """:func:`run_forked` where this process may have children, else :func:`run_isolated`."""
    import multiprocessing

    if multiprocessing.current_process().daemon:
        return run_isolated(job)
    return run_forked(job)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
