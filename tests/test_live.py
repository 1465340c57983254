"""Live inputs, served over loopback (127.0.0.1 only) by servers these tests start and stop.

A generated clip goes out as MPEG-TS over TCP, as MJPEG over HTTP and through
stdin; ``vidtrack`` (the real entry point, in this process under a timeout;
a child process for Ctrl-C) tracks it live: with a tracker that keeps up it
gives the file's boxes, with one slower than the stream it drops frames and
its latency stays within two of its own frame times; a stream that stalls or
is reset ends in one line and exit 1 with every output readable; Ctrl-C ends
a live run with exit 130.
"""

from __future__ import annotations

import csv

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from vidtrack.cli import main

from conftest import synthetic_sequence
from live_helpers import MjpegServer, TsServer, slow_recipe, ts_frame_chunks, write_ts_clip

pytestmark = pytest.mark.timeout(90)   # no test may hang

N_FRAMES = 60
CLIP_FPS = 25
INIT_BOX = "20,40,24,28"
VELOCITY = (1.5, 0.5)   # pixels a frame: the target stays inside the 160x120 frame
SLOW_SECONDS = 0.1
#: FFmpeg releases an MPEG-TS frame once the next two frames' bytes have come (the PES ends where the next
#: begins; the parser then finds the frame's end): a stream sends this many frames more than a test tracks,
#: or its end would release its last two frames together and a busy tracker would drop the first of them
TS_HOLD = 2
SUMMARY = re.compile(r"live: received (\d+), tracked (\d+), dropped (\d+); latency from arrival to result "
                     r"median ([\d.]+) ms, 95th percentile ([\d.]+) ms")


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> tuple[Path, list[bytes], list]:
    """A 160x120 clip of a textured target moving at constant velocity: the .ts file, its frames' bytes, truth."""
    frames, boxes = synthetic_sequence(n=N_FRAMES, size=(160, 120), velocity=VELOCITY)
    path = write_ts_clip(tmp_path_factory.mktemp("clip") / "clip.ts", [f.image for f in frames], fps=CLIP_FPS)
    return path, ts_frame_chunks(path), boxes


@pytest.fixture
def slow_tracker(monkeypatch) -> str:
    """The name of a tracker registered for this test: kalman-cv taking SLOW_SECONDS more per frame."""
    from vidtrack.recipes import registry

    monkeypatch.setitem(registry(), "slow", slow_recipe(SLOW_SECONDS))
    return "slow"


def vidtrack(argv: list[str], capfd, cwd: Path) -> tuple[int, str]:
    """``vidtrack ARGV`` through the console script's entry point in ``cwd``: (exit code, stderr)."""
    here = os.getcwd()
    os.chdir(cwd)
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    finally:
        os.chdir(here)
    return code, capfd.readouterr().err


def summary(stderr: str) -> tuple[int, int, int, float, float]:
    """(received, tracked, dropped, latency median s, latency p95 s) from the live summary line."""
    found = SUMMARY.search(stderr)
    assert found, stderr
    received, tracked, dropped = (int(found.group(i)) for i in (1, 2, 3))
    return received, tracked, dropped, float(found.group(4)) / 1000, float(found.group(5)) / 1000


def tracker_frame_time(stderr: str) -> float:
    """Seconds per frame the tracker took, from the summary's fps."""
    return 1.0 / float(re.search(r"tracked \d+ frames at ([\d.]+) fps", stderr).group(1))


def read_log(path: Path) -> list[dict[str, str]]:
    """The per-frame log's rows (``frame,id,timestamp,x,y,w,h,confidence,status``), one dict each."""
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_tcp_stream_gives_the_files_boxes_when_the_tracker_keeps_up(clip, tmp_path, capfd):
    path, chunks, _ = clip
    frames, fps = 40, 12.5   # 80 ms a frame for a tracker taking a few: it keeps up on a busy machine too
    common = ["--init-box", INIT_BOX, "--filter", "kalman-cv"]
    code, err = vidtrack([str(path), *common, "--boxes", "file.txt", "--max-frames", str(frames)], capfd, tmp_path)
    assert code == 0, err
    with TsServer(chunks[:frames + TS_HOLD], fps) as server:
        code, err = vidtrack([server.url, *common, "--boxes", "live.txt", "--log", "live.csv",
                              "--max-frames", str(frames)], capfd, tmp_path)
    assert code == 0, err
    received, tracked, dropped, _, _ = summary(err)
    assert (tracked, dropped) == (frames, 0) and received >= frames
    assert (tmp_path / "live.txt").read_text() == (tmp_path / "file.txt").read_text()
    rows = read_log(tmp_path / "live.csv")
    assert [int(row["frame"]) for row in rows] == list(range(frames))
    stamps = np.array([float(row["timestamp"]) for row in rows])   # the stream's clock, one frame apart
    np.testing.assert_allclose(np.diff(stamps), 1 / CLIP_FPS, atol=1e-3)


def test_stream_frames_carry_the_streams_timestamps_and_their_arrival(clip):
    from vidtrack.sources import LiveSource, PyAVStream, VideoSource

    path, chunks, _ = clip
    file_frames = list(VideoSource(path))
    with TsServer(chunks, CLIP_FPS) as server:
        frames = list(LiveSource(PyAVStream(server.url, timeout=5), drop=False))   # every frame, none dropped
    assert [frame.index for frame in frames] == list(range(N_FRAMES))
    assert np.allclose([frame.timestamp for frame in frames], [frame.timestamp for frame in file_frames], atol=1e-3)
    assert np.allclose(np.diff([frame.timestamp for frame in file_frames]), 1 / CLIP_FPS, atol=1e-3)
    arrivals = np.array([frame.arrival for frame in frames])
    assert np.all(np.diff(arrivals) > 0) and arrivals[-1] - arrivals[0] > 0.8 * (N_FRAMES - 2) / CLIP_FPS
    assert all(frame.arrival is None for frame in file_frames)


def test_a_tracker_slower_than_the_stream_drops_frames_and_keeps_its_latency(clip, tmp_path, capfd, slow_tracker):
    path, chunks, _ = clip
    with TsServer(chunks, CLIP_FPS) as server:
        code, err = vidtrack([server.url, "--init-box", INIT_BOX, "--filter", slow_tracker, "--log", "live.csv"],
                             capfd, tmp_path)
    assert code == 0, err
    received, tracked, dropped, median, p95 = summary(err)
    frame_time = tracker_frame_time(err)
    assert received == N_FRAMES and dropped > 0 and tracked + dropped == received, err
    assert frame_time >= 0.95 * SLOW_SECONDS   # (the summary rounds the fps)
    assert p95 <= 2 * frame_time, (p95, frame_time)
    indices = [int(row["frame"]) for row in read_log(tmp_path / "live.csv")]
    assert len(indices) == tracked and indices[0] == 0
    assert min(np.diff(indices)) >= 1 and max(np.diff(indices)) > 1   # dropped frames leave gaps in the indices


@pytest.mark.parametrize("cut", ["stall", "reset"])
def test_a_stream_cut_midway_ends_in_one_line_exit_1_and_readable_outputs(clip, tmp_path, capfd, cut):
    path, chunks, _ = clip
    outputs = ["--boxes", "b.txt", "--log", "l.csv", "-o", "o.mp4"]
    with TsServer(chunks, CLIP_FPS, cut_at=20, cut=cut) as server:
        start = time.monotonic()
        code, err = vidtrack([server.url, "--init-box", INIT_BOX, "--filter", "kalman-cv", "--stream-timeout", "1",
                              "-q", *outputs], capfd, tmp_path)
        seconds = time.monotonic() - start
    lines = err.strip().splitlines()
    assert code == 1, err
    assert len(lines) == 1 and lines[0].startswith("vidtrack: error: stream tcp://127.0.0.1:"), err
    assert ("stalled (no data for 1 s)" if cut == "stall" else "broke") in lines[0]
    assert "3 reconnects failed" in lines[0]
    assert seconds >= 3.5   # the reconnects waited 0.5, 1 and 2 s
    boxes = (tmp_path / "b.txt").read_text().splitlines()
    assert 15 <= len(boxes) <= 20
    assert len(read_log(tmp_path / "l.csv")) == len(boxes)
    video = cv2.VideoCapture(str(tmp_path / "o.mp4"))
    assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == len(boxes)
    video.release()


def test_mjpeg_over_http_is_tracked_live(clip, tmp_path, capfd):
    _, _, truth = clip
    frames, _ = synthetic_sequence(n=N_FRAMES, size=(160, 120), velocity=VELOCITY)
    with MjpegServer([f.image for f in frames], CLIP_FPS) as server:
        code, err = vidtrack([server.url, "--init-box", INIT_BOX, "--filter", "kalman-cv", "--log", "l.csv",
                              "--max-frames", "30"], capfd, tmp_path)
    assert code == 0, err
    received, tracked, dropped, _, _ = summary(err)
    assert tracked == 30 and received >= 30
    rows = read_log(tmp_path / "l.csv")
    indices = np.array([int(row["frame"]) for row in rows])
    boxes = np.array([[float(row[k]) for k in "xywh"] for row in rows])
    assert len(indices) == 30 and indices[0] == 0 and min(np.diff(indices)) >= 1
    centres = boxes[:, :2] + boxes[:, 2:] / 2
    true = np.array([[truth[i].x + truth[i].w / 2, truth[i].y + truth[i].h / 2] for i in indices])
    assert np.max(np.linalg.norm(centres - true, axis=1)) < 6   # on the target in every tracked frame


def test_a_video_piped_on_stdin_gives_the_files_boxes(clip, tmp_path, capfd):
    path, _, _ = clip
    common = ["--init-box", INIT_BOX, "--filter", "kalman-cv"]
    code, err = vidtrack([str(path), *common, "--boxes", "file.txt", "-q"], capfd, tmp_path)
    assert code == 0, err
    code, err = on_stdin(path, ["-", *common, "--boxes", "stdin.txt"], capfd, tmp_path)
    assert code == 0, err
    assert summary(err)[:3] == (N_FRAMES, N_FRAMES, 0)   # a pipe holds its writer back: nothing dropped
    assert (tmp_path / "stdin.txt").read_text() == (tmp_path / "file.txt").read_text()


def on_stdin(path: Path, argv: list[str], capfd, cwd: Path) -> tuple[int, str]:
    """``vidtrack ARGV`` with ``path`` on file descriptor 0, as ``vidtrack - < path`` has it."""
    saved = os.dup(0)
    try:
        with open(path, "rb") as file:
            os.dup2(file.fileno(), 0)
        return vidtrack(argv, capfd, cwd)
    finally:
        os.dup2(saved, 0)
        os.close(saved)


def test_stdin_without_a_video_is_one_line_exit_2(tmp_path, capfd):
    (tmp_path / "notes.txt").write_text("not a video\n" * 50)
    code, err = on_stdin(tmp_path / "notes.txt", ["-", "--init-box", "1,1,5,5", "--boxes", "b.txt"], capfd, tmp_path)
    assert code == 2 and err.strip().splitlines() == [
        "vidtrack: error: cannot open the video on stdin: Invalid data found when processing input"], err
    assert not (tmp_path / "b.txt").exists()


def test_a_server_that_never_sends_is_one_line_exit_2_after_the_timeout(tmp_path, capfd):
    with socket.create_server(("127.0.0.1", 0)) as listener:   # accepts (the kernel's backlog), never sends
        url = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
        start = time.monotonic()
        code, err = vidtrack([url, "--init-box", "1,1,5,5", "--stream-timeout", "1", "--boxes", "b.txt"], capfd,
                             tmp_path)
    assert code == 2 and err.strip().splitlines() == [f"vidtrack: error: cannot open stream {url}: no answer "
                                                      f"within 1 s"], err
    assert 1 <= time.monotonic() - start < 10 and not (tmp_path / "b.txt").exists()


def test_realtime_on_a_file_paces_it_and_drops_what_a_slow_tracker_misses(clip, tmp_path, capfd, slow_tracker):
    path, _, _ = clip
    start = time.monotonic()
    code, err = vidtrack([str(path), "--init-box", INIT_BOX, "--filter", "kalman-cv", "--realtime",
                          "--boxes", "rt.txt"], capfd, tmp_path)
    assert code == 0, err
    assert time.monotonic() - start >= (N_FRAMES - 1) / CLIP_FPS   # released at the file's own rate
    received, tracked, dropped, _, _ = summary(err)
    assert received == N_FRAMES and tracked + dropped == received
    code, err = vidtrack([str(path), "--init-box", INIT_BOX, "--filter", slow_tracker, "--realtime"], capfd, tmp_path)
    assert code == 0, err
    received, tracked, dropped, _, p95 = summary(err)
    assert received == N_FRAMES and dropped > 0 and tracked + dropped == received
    assert p95 <= 2 * tracker_frame_time(err)


def test_ctrl_c_ends_a_live_run_with_every_output_finished(clip, tmp_path):
    path, chunks, _ = clip
    boxes = tmp_path / "b.txt"
    with TsServer(chunks, 10) as server:
        process = subprocess.Popen([sys.executable, "-m", "vidtrack", server.url, "--init-box", INIT_BOX,
                                    "--filter", "kalman-cv", "--boxes", str(boxes), "-o", "o.mp4"],
                                   cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True, start_new_session=True)
        try:
            deadline = time.monotonic() + 60
            while not (boxes.exists() and len(boxes.read_text().splitlines()) >= 5):
                assert process.poll() is None and time.monotonic() < deadline, process.communicate()
                time.sleep(0.05)
            process.send_signal(signal.SIGINT)
            _, stderr = process.communicate(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
                process.communicate()
    assert process.returncode == 130, stderr
    assert "interrupted after" in stderr
    tracked = len(boxes.read_text().splitlines())
    assert 5 <= tracked < N_FRAMES
    video = cv2.VideoCapture(str(tmp_path / "o.mp4"))
    assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == tracked
    video.release()


def test_latency_quantiles_from_the_histogram_match_the_exact_ones():
    from vidtrack.cli.live import LatencyStats

    rng = np.random.default_rng(0)
    values = rng.lognormal(np.log(0.02), 0.8, 5000)
    stats = LatencyStats()
    for value in values:
        stats.add(value)
    for q in (0.5, 0.95):
        exact = np.sort(values)[int(np.ceil(q * len(values))) - 1]
        assert stats.quantile(q) == pytest.approx(exact, rel=0.012)
    assert np.isnan(LatencyStats().quantile(0.5))


def test_inputs_are_told_apart():
    from vidtrack.sources import input_kind

    texts = ("-", "0", "12", "rtsp://h/s", "http://h:8080/video.mjpg", "srt://127.0.0.1:9000", "clip.mp4", "./0")
    assert [input_kind(text) for text in texts] == ["stdin", "camera", "camera", "stream", "stream", "stream",
                                                    "file", "file"]


def test_python_api_tracks_a_stream_url_live(clip):
    """``vidtrack.track(URL, ...)`` reads the stream as the command line does: the same boxes as the file."""
    import vidtrack

    path, chunks, _ = clip
    box = tuple(int(v) for v in INIT_BOX.split(","))
    from_file = [s.box for s in vidtrack.track(str(path), box, filter="kalman-cv", max_frames=20)]
    with TsServer(chunks[:20 + TS_HOLD], 12.5) as server:
        live = list(vidtrack.track(server.url, boxes=[box], filter="kalman-cv", max_frames=20))
    assert [states[1].index for states in live] == list(range(20))   # the tracker keeps up: nothing dropped
    np.testing.assert_allclose([states[1].box.as_array() for states in live],
                               [b.as_array() for b in from_file], atol=0.01)
