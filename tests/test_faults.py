"""Faults in the middle of a run, with real child processes: stopping signals (SIGINT, SIGTERM, SIGHUP).

``vidtrack`` stopped by SIGINT or SIGTERM finishes every output (boxes, log,
video, recording with its footer), prints one line and exits 128 + N;
``vidtrack eval`` stopped by SIGTERM keeps its finished results and leaves no
worker process behind.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from hard_stop_helpers import line_count, square_position, write_frames  # noqa: E402

from vidtrack.eval.datasets import read_boxes  # noqa: E402
from vidtrack.sinks.h264 import count_frames  # noqa: E402


def _start(args: list[str], cwd: Path) -> subprocess.Popen:
    """``python -m vidtrack ARGS`` in its own session (so a failed test can end the whole group)."""
    return subprocess.Popen([sys.executable, "-m", "vidtrack", *args], cwd=cwd, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _wait_for(process: subprocess.Popen, ready, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        if process.poll() is not None:
            raise AssertionError(f"vidtrack ended (exit {process.returncode}) too early: {process.stderr.read()}")
        if time.monotonic() > deadline:
            raise AssertionError("vidtrack did not get far enough in time")
        time.sleep(0.01)


def _finish(process: subprocess.Popen, timeout: float = 60.0) -> str:
    """Wait for the process and return its stderr; the whole group is killed if it hangs."""
    import os

    try:
        _, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise AssertionError("vidtrack did not end after the signal") from None
    return stderr


@pytest.mark.parametrize("signum,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130), (signal.SIGHUP, 129)])
def test_a_stopping_signal_finishes_every_output(tmp_path, signum, code):
    frames = write_frames(tmp_path / "img", 3000)
    x, y = square_position(0)
    out = {name: tmp_path / name for name in ("b.txt", "log.csv", "out.mp4", "r.rrd")}
    process = _start([str(frames), "--init-box", f"{x},{y},16,16", "--filter", "kalman-cv", "-q",
                      "--boxes", str(out["b.txt"]), "--log", str(out["log.csv"]), "-o", str(out["out.mp4"]),
                      "--rerun", str(out["r.rrd"])], tmp_path)
    _wait_for(process, lambda: line_count(out["b.txt"]) >= 100)
    process.send_signal(signum)          # the process only, as docker stop or a scheduler sends it
    stderr = _finish(process)
    assert process.returncode == code, stderr
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1, stderr
    tracked = int(re.fullmatch(r"vidtrack: interrupted after (\d+) frames \((SIG\w+)\).*", lines[0]).group(1))
    assert signal.Signals(signum).name in lines[0]
    assert 100 <= tracked < 3000
    assert len(read_boxes(out["b.txt"])) == tracked             # every box, each line complete
    assert line_count(out["log.csv"]) == tracked + 1            # and the header
    assert count_frames(out["out.mp4"]) == tracked              # the open fragment is written too

    from rerun_reader import read_recording

    with warnings.catch_warnings():
        warnings.simplefilter("error")                          # a finished recording has its footer
        recorded = read_recording(out["r.rrd"])["video/frame"]
    assert recorded == list(range(tracked))


def _dataset(root: Path) -> Path:
    """OTB-style sequences of the moving square: ``Alpha`` (40 frames), then ``Beta`` and ``Gamma`` (4000 each)."""
    for name, count in (("Alpha", 40), ("Beta", 4000), ("Gamma", 4000)):
        folder = write_frames(root / name / "img", count)
        rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(count))]
        (folder.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root


@pytest.mark.parametrize("jobs", [1, 2])
def test_sigterm_of_eval_keeps_finished_results_and_ends_its_workers(tmp_path, jobs):
    psutil = pytest.importorskip("psutil")
    data = _dataset(tmp_path / "data")
    out = tmp_path / "out"
    process = _start(["eval", str(data), "--filter", "kalman-cv", "--no-plots", "--jobs", str(jobs), "-q",
                      "--out", str(out)], tmp_path)
    alpha = out / "kalman-cv" / "Alpha.json"
    _wait_for(process, alpha.exists)
    parent = psutil.Process(process.pid)
    _wait_for(process, lambda: len(parent.children(recursive=True)) >= 1 + jobs)   # fork server + running jobs
    descendants = parent.children(recursive=True)
    process.send_signal(signal.SIGTERM)
    stderr = _finish(process)
    assert process.returncode == 143, stderr
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert lines == ["vidtrack: interrupted (SIGTERM); every finished output is kept"], stderr

    deadline = time.monotonic() + 10
    alive = descendants
    while alive and time.monotonic() < deadline:
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        time.sleep(0.05)
    assert not alive, [p.cmdline() for p in alive]

    record = json.loads(alpha.read_text())                       # the finished result is intact
    assert record["sequence"] == "Alpha"
    assert len(read_boxes(out / "kalman-cv" / "Alpha.txt")) == 40
    assert not (out / "kalman-cv" / "Beta.json").exists() and not (out / "summary.json").exists()
    assert not list(out.rglob("*.part"))
