"""A Dask worker lost in the middle of a ``vidtrack eval --scheduler`` job, with real processes.

A scheduler and two workers run on 127.0.0.1 as child processes; the worker
running the long job is killed by its PID (as the OOM killer would).  The
scheduler runs the job again on another worker (the other one, or the one a
nanny restarts), its result and recording are written whole, the results
finished before are untouched, the job's own process does not outlive its
worker, and the evaluation exits 0.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from hard_stop_helpers import square_position, write_frames  # noqa: E402

from vidtrack.eval.datasets import read_boxes  # noqa: E402

pytest.importorskip("dask.distributed")
psutil = pytest.importorskip("psutil")

LONG = 4000


def _dataset(root: Path, cache: Path) -> Path:
    for name, count in (("Alpha", 20), ("Beta", LONG), ("Gamma", 20)):
        folder = write_frames(root / name / "img", count, cache)
        rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(count))]
        (folder.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root


def _wait(ready, what: str, timeout: float = 90.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = ready()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.fixture(params=["worker", "worker under a nanny"])
def cluster(request, tmp_path):
    """A scheduler and two single-thread workers on 127.0.0.1: plain (the job forks from the worker) or each
    under a nanny (daemonic: the job runs in a child interpreter); the worker processes' PIDs."""
    python = [sys.executable, "-m"]
    address_file = tmp_path / "scheduler.json"
    processes = [subprocess.Popen([*python, "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                                   "--no-dashboard", "--scheduler-file", str(address_file)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        nanny = ["--nanny"] if "nanny" in request.param else ["--no-nanny"]
        for _ in range(2):   # started beside the scheduler: a worker waits for the scheduler file
            processes.append(subprocess.Popen([*python, "distributed.cli.dask_worker", "--scheduler-file",
                                               str(address_file), "--nthreads", "1", "--no-dashboard",
                                               "--host", "127.0.0.1", *nanny],
                                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                              start_new_session=True))
        address = _wait(lambda: address_file.exists() and json.loads(address_file.read_text() or "{}").get("address"),
                        "the scheduler's address")
        from dask.distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=90)
            pids = list(client.run(lambda: __import__("os").getpid()).values())
        yield address, pids
    finally:
        for process in reversed(processes):
            for child in psutil.Process(process.pid).children(recursive=True) if process.poll() is None else []:
                child.kill()
            process.kill()
            process.wait()


def _writing(path: Path, workers: list[int]):
    """(worker PID, job process) of the job process under one of ``workers`` that has ``path`` open, else None."""
    for worker in workers:
        try:
            descendants = psutil.Process(worker).children(recursive=True)
        except psutil.NoSuchProcess:
            continue
        for process in descendants:
            try:
                if any(Path(f.path) == path for f in process.open_files()):
                    return worker, process
            except psutil.Error:
                continue
    return None


def _ended(process, timeout: float) -> bool:
    """Whether ``process`` ends within ``timeout`` s: gone, or a zombie (dead; an orphan waits for init to reap it)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if process.status() == psutil.STATUS_ZOMBIE:
                return True
        except psutil.NoSuchProcess:
            return True
        time.sleep(0.02)
    return False


def test_a_lost_workers_job_is_run_again_on_another_worker(tmp_path, square_frames, cluster):
    address, workers = cluster
    data = _dataset(tmp_path / "data", square_frames)
    out, recordings = tmp_path / "out", tmp_path / "rerun"
    evaluation = subprocess.Popen([sys.executable, "-m", "vidtrack", "eval", str(data), "--filter", "kalman-cv",
                                   "--no-plots", "-q", "--out", str(out), "--rerun", str(recordings),
                                   "--scheduler", address],
                                  cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, start_new_session=True)
    results = {name: out / "kalman-cv" / f"{name}.json" for name in ("Alpha", "Beta", "Gamma")}
    try:
        beta = recordings / "kalman-cv" / "Beta.rrd"
        worker, job = _wait(lambda: _writing(beta, workers), "Beta's job")   # the job process writing Beta
        finished = {path: path.read_bytes() for path in results.values() if path.exists()}
        assert results["Beta"] not in finished
        psutil.Process(worker).send_signal(signal.SIGKILL)            # the worker is lost mid-job
        assert _ended(job, timeout=3), job                            # its job dies with it, long before its end
        _, stderr = evaluation.communicate(timeout=180)
    finally:
        if evaluation.poll() is None:
            evaluation.kill()
            evaluation.communicate()
    assert evaluation.returncode == 0, stderr
    assert "Traceback" not in stderr, stderr
    counts = {"Alpha": 20, "Beta": LONG, "Gamma": 20}
    for name, path in results.items():                                # each written whole, Beta by another worker
        assert json.loads(path.read_text())["sequence"] == name
        assert len(read_boxes(path.with_suffix(".txt"))) == counts[name]
    assert all(path.read_bytes() == text for path, text in finished.items())   # finished ones untouched
    from rerun_reader import read_recording

    assert read_recording(beta)["video/frame"] == list(range(LONG))  # the recording of the run that finished
    assert not list(out.rglob("*.part"))


def test_a_job_whose_every_worker_was_lost_is_failed_for_its_sequence_only(tmp_path):
    from types import SimpleNamespace

    from distributed.scheduler import KilledWorker

    from vidtrack.eval.jobs import Job
    from vidtrack.eval.running import _failed
    from vidtrack.eval.sequence import BenchmarkSequence
    from vidtrack.eval.worker import died

    sequence = BenchmarkSequence("Beta", tmp_path, (), np.zeros((0, 4)), 1, "otb", (0, 0))
    output = _failed(Job("kalman-cv", sequence), KilledWorker("run_fresh-1", SimpleNamespace(address="tcp://x"), 3))
    assert (output.filter_name, output.sequence_name, output.status) == ("kalman-cv", "Beta", "failed")
    assert output.error == "worker process died (on the 4 Dask workers that ran it)" and died(output)
