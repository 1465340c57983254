"""Faults in the middle of a run, with real child processes: stopping signals, undecodable frames, a full disk,
dying eval jobs and Dask workers, concurrent evals, awkward and read-only paths, a cbt grid over its budget.

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

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from hard_stop_helpers import mounted_tmpfs, line_count, square_position, write_frames  # noqa: E402

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
def test_a_stopping_signal_finishes_every_output(tmp_path, square_frames, signum, code):
    frames = write_frames(tmp_path / "img", 3000, square_frames)
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


def _otb(root: Path, counts: dict[str, int], cache: Path) -> Path:
    """OTB-style sequences of the moving square under ``root``: ``{name: frame count}``, frames from ``cache``."""
    for name, count in counts.items():
        folder = write_frames(root / name / "img", count, cache)
        rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(count))]
        (folder.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root


@pytest.mark.parametrize("jobs", [1, 2])
def test_sigterm_of_eval_keeps_finished_results_and_ends_its_workers(tmp_path, square_frames, jobs):
    psutil = pytest.importorskip("psutil")
    data = _otb(tmp_path / "data", {"Alpha": 40, "Beta": 4000, "Gamma": 4000}, square_frames)
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


def _jpeg_frames(folder: Path, count: int) -> Path:
    import cv2

    from hard_stop_helpers import square_frame

    folder.mkdir(parents=True)
    for index in range(count):
        cv2.imwrite(str(folder / f"{index:04d}.jpg"), square_frame(index), [cv2.IMWRITE_JPEG_QUALITY, 95])
    return folder


def test_undecodable_frames_in_a_folder_are_skipped_and_predicted_through(tmp_path):
    import shutil

    clean = _jpeg_frames(tmp_path / "clean", 300)
    broken = tmp_path / "broken copy ü"
    shutil.copytree(clean, broken)
    (broken / "0120.jpg").write_bytes(b"\x00garbage" * 100)                     # not a JPEG at all
    data = (broken / "0200.jpg").read_bytes()
    (broken / "0200.jpg").write_bytes(data[: len(data) // 2])                   # a copy cut short
    x, y = square_position(0)
    started = {name: _start([str(folder), "--init-box", f"{x},{y},16,16", "--filter", "kalman-cv",
                             "--boxes", str(tmp_path / f"{name}.txt"), "--log", str(tmp_path / f"{name}.csv")],
                            tmp_path)
               for name, folder in (("clean", clean), ("broken", broken))}      # the two runs side by side
    runs = {}
    for name, process in started.items():
        stderr = _finish(process, timeout=300)
        runs[name] = (process.returncode, stderr, read_boxes(tmp_path / f"{name}.txt"),
                      (tmp_path / f"{name}.csv").read_text().splitlines()[1:])
    code, stderr, boxes, log = runs["broken"]
    assert code == 0, stderr
    assert "Traceback" not in stderr
    warnings_ = [line for line in stderr.splitlines() if "warning" in line]
    assert len(warnings_) == 2, stderr
    assert "0120.jpg" in warnings_[0] and "frame 120 skipped" in warnings_[0]
    assert "0200.jpg" in warnings_[1] and "truncated" in warnings_[1] and "frame 200 skipped" in warnings_[1]
    assert "2 undecodable skipped" in stderr                                     # counted in the summary
    assert len(boxes) == 300 and [int(row.split(",")[0]) for row in log] == list(range(300))
    clean_boxes = runs["clean"][2]
    assert boxes[:120].tolist() == clean_boxes[:120].tolist()                    # the same run up to the gap
    assert boxes[120].tolist() != clean_boxes[120].tolist()                      # a prediction, not a measurement
    tx, ty = square_position(299)                                                # tracking goes on after the gaps
    assert abs(boxes[-1][0] - tx) < 4 and abs(boxes[-1][1] - ty) < 4, boxes[-1]


def test_a_broken_first_frame_is_still_bad_input(tmp_path):
    folder = _jpeg_frames(tmp_path / "frames", 5)
    (folder / "0000.jpg").write_bytes(b"garbage")
    done = subprocess.run([sys.executable, "-m", "vidtrack", str(folder), "--init-box", "1,1,16,16",
                           "--filter", "kalman-cv", "-q", "--boxes", str(tmp_path / "b.txt")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [f"vidtrack: error: cannot decode image {folder / '0000.jpg'}"]
    assert not (tmp_path / "b.txt").exists()


def test_eval_predicts_through_an_undecodable_frame_and_records_it(tmp_path):
    import shutil

    data = tmp_path / "data"
    images = _jpeg_frames(data / "Square" / "img", 80)
    rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(80))]
    (images.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    clean = tmp_path / "clean"
    shutil.copytree(data, clean)
    (images / "0040.jpg").write_bytes(b"garbage")
    outs = {name: tmp_path / f"out-{name}" for name in ("broken", "clean")}
    started = [_start(["eval", str(dataset), "--filter", "kalman-cv", "--no-plots", "-q", "--out", str(outs[name])],
                      tmp_path) for name, dataset in (("broken", data), ("clean", clean))]   # side by side
    for process in started:
        stderr = _finish(process, timeout=300)
        assert process.returncode == 0, stderr
        assert "Traceback" not in stderr
    record = json.loads((outs["broken"] / "kalman-cv" / "Square.json").read_text())
    assert [s["row"] for s in record["skipped"]] == [40] and "0040.jpg" in record["skipped"][0]["reason"]
    assert "skipped" not in json.loads((outs["clean"] / "kalman-cv" / "Square.json").read_text())
    broken = read_boxes(outs["broken"] / "kalman-cv" / "Square.txt")
    clean_boxes = read_boxes(outs["clean"] / "kalman-cv" / "Square.txt")
    assert len(broken) == 80 and broken[:40].tolist() == clean_boxes[:40].tolist()


def _mkv(path: Path, count: int) -> bytes:
    """The moving square as H.264 in Matroska (a keyframe every 10 frames); its bytes."""
    from hard_stop_helpers import square_frame

    from vidtrack.sinks.h264 import H264Writer

    writer = H264Writer(path, fps=30.0, batch=10)
    for index in range(count):
        writer.write(square_frame(index))
    writer.close()
    return path.read_bytes()


def _track(video: Path, boxes: Path, cwd: Path) -> subprocess.CompletedProcess:
    x, y = square_position(0)
    return subprocess.run([sys.executable, "-m", "vidtrack", str(video), "--init-box", f"{x},{y},16,16",
                           "--filter", "kalman-cv", "-q", "--boxes", str(boxes)],
                          cwd=cwd, capture_output=True, text=True, timeout=300)


def test_a_video_with_garbage_in_the_middle_resynchronises_and_keeps_frame_indices(tmp_path):
    import random

    data = _mkv(tmp_path / "whole.mkv", 300)
    middle = len(data) // 2
    garbage = random.Random(0).randbytes(3000)
    broken = tmp_path / "garbage in the middle.mkv"
    broken.write_bytes(data[:middle] + garbage + data[middle:])
    done = _track(broken, tmp_path / "b.txt", tmp_path)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if "libav" not in line and not line.startswith("[")]
    assert len(lines) == 1, done.stderr
    first, last = map(int, re.search(r"frames (\d+)-(\d+) did not decode", lines[0]).groups())
    assert 0 < first <= last < 299
    boxes = read_boxes(tmp_path / "b.txt")
    assert len(boxes) == 300                                # one box per frame of the video, the gap predicted

    from vidtrack.sources import VideoSource

    clean = [frame.image for frame in VideoSource(tmp_path / "whole.mkv")]
    source = VideoSource(broken)
    frames = list(source)
    assert [frame.index for frame in frames] == list(range(300))
    assert source.missing == set(range(first, last + 1))
    for frame in frames:   # every decoded frame at its own index (FFmpeg conceals the damage in the one before)
        if frame.index not in source.missing and frame.index != first - 1:
            assert abs(frame.image.astype(int) - clean[frame.index]).mean() < 1.0, frame.index


def test_a_video_cut_short_keeps_every_tracked_frame_and_warns_once(tmp_path):
    data = _mkv(tmp_path / "whole.mkv", 300)
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[: len(data) // 2])
    done = _track(cut, tmp_path / "b.txt", tmp_path)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("vidtrack")]
    assert len(lines) == 1 and "warning: decoding stopped at frame" in lines[0], done.stderr
    kept = int(re.search(r"kept the (\d+) frames", lines[0]).group(1))
    assert 50 < kept < 300 and len(read_boxes(tmp_path / "b.txt")) == kept


@pytest.fixture
def small_disk(tmp_path):
    """A 64 KB tmpfs folder (mounted for the test: needs root, as on this project's machines and CI)."""
    yield from mounted_tmpfs(tmp_path / "small disk", "64k")


def test_a_full_disk_while_tracking_is_one_line_exit_1_and_every_file_stays_valid(tmp_path, square_frames,
                                                                                    small_disk):
    import csv

    frames = write_frames(tmp_path / "img", 3000, square_frames)
    x, y = square_position(0)
    out = {name: small_disk / name for name in ("b.txt", "log.csv", "out.mp4")}
    done = subprocess.run([sys.executable, "-m", "vidtrack", str(frames), "--init-box", f"{x},{y},16,16",
                           "--filter", "kalman-cv", "-q", "--flush-every", "10", "--boxes", str(out["b.txt"]),
                           "--log", str(out["log.csv"]), "-o", str(out["out.mp4"])],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left on device" in lines[0] and "Traceback" not in done.stderr, done.stderr
    written = int(re.search(r"keep the (\d+) frames", lines[0]).group(1))
    assert 0 < written < 3000
    boxes = read_boxes(out["b.txt"])                                   # every line complete
    with open(out["log.csv"], newline="") as file:
        rows = list(csv.reader(file))
    assert rows[0] == ["frame", "id", "timestamp", "x", "y", "w", "h", "confidence", "status"]
    assert all(len(row) == 9 for row in rows[1:])
    assert [int(row[0]) for row in rows[1:]] == list(range(len(rows) - 1))
    assert written <= len(boxes) <= written + 1 and written <= len(rows) - 1 <= written + 1
    assert count_frames(out["out.mp4"]) <= written + 1                 # PyAV reads what the video holds


def test_a_full_disk_in_eval_keeps_finished_results_and_is_exit_1(tmp_path, square_frames, small_disk):
    # Beta's result and confidence files alone (about 45 bytes a frame) are more than the 64 KB disk holds
    data = _otb(tmp_path / "data", {"Alpha": 30, "Beta": 1500}, square_frames)
    done = subprocess.run([sys.executable, "-m", "vidtrack", "eval", str(data), "--filter", "kalman-cv",
                           "--no-plots", "-q", "--out", str(small_disk)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left on device" in lines[0] and "Traceback" not in done.stderr, done.stderr
    record = json.loads((small_disk / "kalman-cv" / "Alpha.json").read_text())   # the finished result, whole
    assert record["sequence"] == "Alpha" and len(read_boxes(small_disk / "kalman-cv" / "Alpha.txt")) == 30
    assert not (small_disk / "kalman-cv" / "Beta.json").exists()
    assert not list(small_disk.rglob("*.part"))


def _job_processes(psutil, parent) -> list:
    """The job processes of a ``vidtrack eval`` process: the children of its fork server."""
    servers = [p for p in parent.children() if "forkserver" in " ".join(p.cmdline())]
    return [child for server in servers for child in server.children()]


#: Frames of the job that is killed: a second or more of tracking, so it is still running when killed.
BETA = 1000


@pytest.mark.parametrize("kills", [1, 2])
def test_a_killed_job_is_run_again_once_then_failed_for_its_sequence_only(tmp_path, square_frames, kills):
    psutil = pytest.importorskip("psutil")
    data = _otb(tmp_path / "data", {"Alpha": 30, "Beta": BETA, "Gamma": 30}, square_frames)
    out = tmp_path / "out"
    process = _start(["eval", str(data), "--filter", "kalman-cv", "--no-plots", "--jobs", "1", "--out", str(out)],
                     tmp_path)
    _wait_for(process, (out / "kalman-cv" / "Alpha.json").exists)   # jobs run in order: Beta's is next
    parent, killed = psutil.Process(process.pid), set()
    for _ in range(kills):
        _wait_for(process, lambda: [p for p in _job_processes(psutil, parent) if p.pid not in killed])
        job = next(p for p in _job_processes(psutil, parent) if p.pid not in killed)
        job.kill()                                                    # as the OOM killer would
        killed.add(job.pid)
    stderr = _finish(process, timeout=300)
    assert "Traceback" not in stderr, stderr
    assert (out / "kalman-cv" / "Gamma.json").exists(), (process.returncode, stderr)
    for name in ("Alpha", "Gamma"):
        assert json.loads((out / "kalman-cv" / f"{name}.json").read_text())["sequence"] == name
    summary = json.loads((out / "summary.json").read_text())
    assert summary
    if kills == 1:                                                    # run again, and this time it finished
        assert process.returncode == 0, stderr
        assert len(read_boxes(out / "kalman-cv" / "Beta.txt")) == BETA
    else:
        assert process.returncode == 1, stderr
        failed = [line for line in stderr.splitlines() if "FAILED" in line]
        assert len(failed) == 1 and re.fullmatch(r"vidtrack eval: kalman-cv FAILED on Beta: worker process died "
                                                 r"\((killed by signal 9|while it was started)\), also when run again",
                                                 failed[0]), stderr
        assert not (out / "kalman-cv" / "Beta.json").exists()


#: Frames of each sequence the two evaluations write at the same time.
FRAMES = 100


def test_two_evals_on_one_folder_leave_whole_results(tmp_path, square_frames):
    names = ("Alpha", "Beta", "Gamma")
    data = _otb(tmp_path / "data", dict.fromkeys(names, FRAMES), square_frames)
    out = tmp_path / "out"
    command = ["eval", str(data), "--filter", "kalman-cv,ms", "--no-plots", "-q", "--force", "--out", str(out)]
    first, second = _start(command, tmp_path), _start(command, tmp_path)   # both write every result
    for process in (first, second):
        stderr = _finish(process, timeout=300)
        assert process.returncode == 0, stderr
        assert "Traceback" not in stderr, stderr
    for tracker in ("kalman-cv", "ms"):
        for name in names:
            assert len(read_boxes(out / tracker / f"{name}.txt")) == FRAMES
            assert json.loads((out / tracker / f"{name}.json").read_text())["sequence"] == name
    assert not list(out.rglob("*.part"))


def test_a_cbt_grid_over_its_memory_budget_is_refused_in_one_line(tmp_path, square_frames):
    frames = write_frames(tmp_path / "img", 3, square_frames)
    x, y = square_position(0)
    done = subprocess.run([sys.executable, "-m", "vidtrack", str(frames), "--init-box", f"{x},{y},16,16",
                           "--filter", "cbt", "--set", "grid.spacing_boxes=0.01", "--set", "grid.min_spacing=0.1",
                           "--set", "order=3", "-q", "--boxes", str(tmp_path / "b.txt")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and not (tmp_path / "b.txt").exists()
    assert re.fullmatch(r"vidtrack: error: cbt: a position grid of \d+x\d+ channels of order 3 needs \d+ MB, over "
                        r"the 512 MB budget; raise grid.spacing_boxes or lower grid.window_boxes or order\n", done.stderr)


def test_opencv_tld_over_its_memory_budget_is_refused_in_one_line(tmp_path):
    import cv2

    folder = tmp_path / "4k"
    folder.mkdir()
    cv2.imwrite(str(folder / "0000.png"), np.full((2160, 3840, 3), 80, np.uint8))
    done = subprocess.run([sys.executable, "-m", "vidtrack", str(folder), "--init-box", "1900,1000,10,10",
                           "--filter", "opencv-tld", "-q", "--boxes", str(tmp_path / "b.txt")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and not (tmp_path / "b.txt").exists()
    assert re.fullmatch(r"vidtrack: error: opencv-tld scans the whole frame: a 10x10 box on a 3840x2160 frame needs "
                        r"about \d+ MB, over its 512 MB budget; use a larger box or a downscaled video\n",
                        done.stderr), done.stderr
