"""The vidtrack command end to end: every filter on the bundled sample, and bad input."""

import csv
import subprocess
import sys

import cv2
import numpy as np
import pytest

from vidtrack.cli import main
from vidtrack.recipes import registry

from conftest import SAMPLE_GT, SAMPLE_VIDEO

FRAMES = 25


def vidtrack(*args, cwd=None):
    """Run the CLI in a subprocess (to see exit code, stderr and the absence of tracebacks)."""
    return subprocess.run([sys.executable, "-m", "vidtrack", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


@pytest.mark.parametrize("name", sorted(registry()))
def test_every_filter_writes_one_box_per_frame(name, tmp_path, sample_init_box):
    boxes, log = tmp_path / "b.txt", tmp_path / "log.csv"
    code = main([str(SAMPLE_VIDEO), "--init-box", sample_init_box, "--filter", name, "--boxes", str(boxes),
                 "--log", str(log), "--max-frames", str(FRAMES), "--quiet"])
    assert code == 0
    lines = boxes.read_text().splitlines()
    assert len(lines) == FRAMES
    assert lines[0] == sample_init_box
    assert all(len(line.split(",")) == 4 for line in lines)
    rows = list(csv.DictReader(log.open()))
    assert len(rows) == FRAMES and set(rows[0]) == {"frame", "id", "timestamp", "x", "y", "w", "h", "confidence", "status"}


def test_whole_sample_tracked_with_annotated_video(tmp_path, sample_init_box):
    out, boxes = tmp_path / "out.mp4", tmp_path / "b.txt"
    result = vidtrack(SAMPLE_VIDEO, "--init-box", sample_init_box, "--filter", "kalman-cv", "-o", out,
                      "--boxes", boxes)
    assert result.returncode == 0, result.stderr
    assert "tracked 150 frames" in result.stderr
    truth = np.loadtxt(SAMPLE_GT, delimiter=",")
    tracked = np.loadtxt(boxes, delimiter=",")
    assert tracked.shape == truth.shape
    capture = cv2.VideoCapture(str(out))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 150
    ok, frame = capture.read()
    assert ok and frame.shape == (240, 320, 3)


def test_frame_folder_input(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    capture = cv2.VideoCapture(str(SAMPLE_VIDEO))
    for k in range(8):
        ok, frame = capture.read()
        cv2.imwrite(str(folder / f"{k:04d}.png"), frame)
    (folder / "notes.txt").write_text("not an image")
    boxes = tmp_path / "b.txt"
    assert main([str(folder), "--init-box", SAMPLE_GT.read_text().splitlines()[0], "--filter", "ms",
                 "--boxes", str(boxes), "--quiet"]) == 0
    assert len(boxes.read_text().splitlines()) == 8


def test_filters_subcommand_lists_every_filter(capsys):
    assert main(["filters"]) == 0
    out = capsys.readouterr().out
    for name in registry():
        assert name in out


BAD_INPUTS = {
    "missing video": (["nope.mp4", "--init-box", "1,1,5,5"], "no such"),
    "folder without images": (["{empty}", "--init-box", "1,1,5,5"], "no images"),
    "broken video": (["{broken}", "--init-box", "1,1,5,5"], "cannot decode"),
    "malformed box": (["{video}", "--init-box", "1,2,three,4"], "four numbers"),
    "three numbers": (["{video}", "--init-box", "1,2,3"], "four numbers"),
    "zero size": (["{video}", "--init-box", "10,10,0,5"], "positive"),
    "negative size": (["{video}", "--init-box", "10,10,5,-5"], "positive"),
    "box outside": (["{video}", "--init-box", "1000,1000,20,20"], "outside"),
    "unknown filter": (["{video}", "--init-box", "1,1,5,5", "--filter", "nope"], "kalman-cv"),
    "unwritable boxes": (["{video}", "--init-box", "1,1,5,5", "--boxes", "/proc/vidtrack/b.txt"], "cannot write"),
    "unwritable video": (["{video}", "--init-box", "1,1,5,5", "-o", "/proc/vidtrack/o.mp4"], "cannot write"),
    "missing option": (["{video}"], "init-box"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_one_line_and_exit_2(case, tmp_path):
    args, expected = BAD_INPUTS[case]
    empty = tmp_path / "empty"
    empty.mkdir()
    broken = tmp_path / "broken.mp4"
    # Fixed bytes: some random draws happen to parse as a container FFmpeg knows.
    broken.write_bytes(np.random.default_rng(0).bytes(2000))
    args = [a.format(empty=empty, broken=broken, video=SAMPLE_VIDEO) for a in args]
    result = vidtrack(*args, "--quiet", cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert expected in lines[0]


def test_video_failing_part_way_keeps_tracked_frames(tmp_path, sample_init_box):
    # An MJPG AVI cut in half: the header promises 150 frames, about half decode.
    capture = cv2.VideoCapture(str(SAMPLE_VIDEO))
    whole = tmp_path / "whole.avi"
    writer = cv2.VideoWriter(str(whole), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (320, 240))
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        writer.write(frame)
    writer.release()
    data = whole.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    boxes = tmp_path / "b.txt"
    result = vidtrack(cut, "--init-box", sample_init_box, "--filter", "ms", "--boxes", boxes, "--quiet")
    assert result.returncode == 0     # what was tracked is the result; one warning says the video ended early
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "warning: decoding stopped at frame" in lines[0] and "kept the" in lines[0]
    kept = boxes.read_text().splitlines()
    assert 20 < len(kept) < 150
    assert f"kept the {len(kept)} frames" in lines[0]


def test_face_detector_tracks_a_face(tmp_path):
    """NormalHedge over OpenCV's Haar face cascade (shipped in the wheel) follows a real face."""
    from conftest import SEQUENCES

    sequence = SEQUENCES / "FaceOcc1"
    if not sequence.is_dir():
        pytest.skip("shared benchmark sequences not present")
    boxes = tmp_path / "b.txt"
    # OTB ground truth is 1-based: 118,69,114,162 -> 0-based init box.
    assert main([str(sequence / "img"), "--init-box", "117,68,114,162", "--filter", "nh", "--detector", "face",
                 "--boxes", str(boxes), "--max-frames", "40", "--quiet"]) == 0
    tracked = np.loadtxt(boxes, delimiter=",")
    truth = np.loadtxt(sequence / "groundtruth_rect.txt", delimiter=",")[:40]
    truth[:, :2] -= 1
    error = np.hypot(*((tracked[:, :2] + tracked[:, 2:] / 2) - (truth[:, :2] + truth[:, 2:] / 2)).T)
    assert error.mean() < 15.0


@pytest.mark.parametrize("name", ["opencv-mil", "opencv-tld"])
def test_opencv_runs_reproducible_across_processes(name, tmp_path, sample_init_box):
    outputs = []
    for run in range(2):
        boxes = tmp_path / f"b{run}.txt"
        result = vidtrack(SAMPLE_VIDEO, "--init-box", sample_init_box, "--filter", name, "--boxes", boxes,
                          "--max-frames", "40", "--seed", "5", "--quiet")
        assert result.returncode == 0, result.stderr
        outputs.append(boxes.read_text())
    assert outputs[0] == outputs[1]


def test_ctrl_c_keeps_every_tracked_frame(tmp_path, sample_init_box):
    import re
    import signal
    import time

    # A frame folder long enough that the run is still going when interrupted.
    images, folder_frames = 150, 3000
    folder = tmp_path / "frames"
    folder.mkdir()
    capture = cv2.VideoCapture(str(SAMPLE_VIDEO))
    for k in range(images):
        ok, frame = capture.read()
        assert ok
        cv2.imwrite(str(folder / f"{k:04d}.png"), frame)
    for k in range(images, folder_frames):  # the same images again, so the run outlasts a slow poll
        (folder / f"{k:04d}.png").symlink_to(folder / f"{k % images:04d}.png")
    boxes, log = tmp_path / "b.txt", tmp_path / "log.csv"
    process = subprocess.Popen([sys.executable, "-m", "vidtrack", str(folder), "--init-box", sample_init_box,
                                "--filter", "svk", "--boxes", str(boxes), "--log", str(log)],
                               stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and (not boxes.exists() or len(boxes.read_text().splitlines()) < 5):
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130
    assert "Traceback" not in stderr
    tracked = int(re.search(r"interrupted after (\d+) frames", stderr).group(1))
    assert 5 <= tracked < folder_frames
    assert len(boxes.read_text().splitlines()) == tracked
    assert len(log.read_text().splitlines()) == tracked + 1  # header


@pytest.mark.parametrize("name,flag,value", [("ms", "--detector", "face"), ("kalman-cv", "--detector", "face"),
                                             ("opencv-kcf", "--model", "m.npz"), ("nh", "--model", "m.npz")])
def test_a_cli_option_the_filter_does_not_take_is_one_line_exit_2(name, flag, value, sample_init_box, capsys):
    assert main([str(SAMPLE_VIDEO), "--init-box", sample_init_box, "--filter", name, flag, value, "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"filter {name}: unknown option '{flag[2:]}'; valid options: " in err[0]
