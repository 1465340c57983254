"""Hard stops: ``kill -9`` of ``vidtrack`` and of ``vidtrack eval`` mid-run.

Every output of a killed ``vidtrack`` run stays readable and loses at most
the frames after its last flush (``--flush-every``); a killed evaluation,
run again, reuses only complete results and ends with the summary of an
uninterrupted run.
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from hard_stop_helpers import line_count, run_and_kill, square_position, write_frames  # noqa: E402

from vidtrack.eval.datasets import read_boxes  # noqa: E402
from vidtrack.sinks.h264 import count_frames  # noqa: E402

FLUSH = 10


def test_kill_9_keeps_boxes_log_video_and_recording(tmp_path, square_frames):
    frames = write_frames(tmp_path / "img", 2500, square_frames)
    x, y = square_position(0)
    out = {name: tmp_path / name for name in ("boxes.txt", "log.csv", "video.mp4", "rec.rrd")}
    run_and_kill([str(frames), "--init-box", f"{x},{y},16,16", "--filter", "kalman-cv", "-q",
                  "--flush-every", str(FLUSH), "--boxes", str(out["boxes.txt"]), "--log", str(out["log.csv"]),
                  "-o", str(out["video.mp4"]), "--rerun", str(out["rec.rrd"])],
                 out["boxes.txt"], 300, cwd=tmp_path)
    boxes = read_boxes(out["boxes.txt"])           # every line complete and parseable
    assert 300 <= len(boxes) < 2500                 # killed mid-run
    logged = line_count(out["log.csv"]) - 1         # minus the header
    assert abs(logged - len(boxes)) <= 1            # the sinks write one after the other
    video_frames = count_frames(out["video.mp4"])   # PyAV decodes the killed run's video
    assert 0 <= len(boxes) - video_frames <= FLUSH + 1, (len(boxes), video_frames)

    from rerun_reader import read_recording

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")             # "no footer": expected after kill -9
        recorded = read_recording(out["rec.rrd"])["video/frame"]
    assert recorded == list(range(len(recorded)))   # no gap
    assert 0 <= len(boxes) - len(recorded) <= FLUSH + 1, (len(boxes), len(recorded))


#: Frames of ``Beta``, the sequence being tracked when the evaluation is killed: a second or more of tracking.
BETA = 500


def _dataset(root: Path, cache: Path) -> Path:
    """Two OTB-style sequences of the moving square: ``Alpha`` (60 frames), then ``Beta`` (``BETA``)."""
    for name, count in (("Alpha", 60), ("Beta", BETA)):
        folder = write_frames(root / name / "img", count, cache)
        rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(count))]
        (folder.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root


def _summary(out: Path) -> dict:
    """``summary.json`` without the fps (timings differ between runs; every score must not)."""
    summary = json.loads((out / "summary.json").read_text())

    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k != "fps"}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value
    return strip(summary)


def test_kill_9_of_eval_then_again_equals_an_uninterrupted_run(tmp_path, square_frames):
    data = _dataset(tmp_path / "data", square_frames)
    command = [str(data), "--filter", "kalman-cv", "--no-plots", "--jobs", "1"]
    killed = tmp_path / "killed"
    # jobs run in sequence order: once Alpha's record exists, Beta is being tracked: kill it there
    run_and_kill(["eval", *command, "-q", "--out", str(killed)], killed / "kalman-cv" / "Alpha.json", 0, cwd=tmp_path)
    assert not (killed / "summary.json").exists()
    assert not (killed / "kalman-cv" / "Beta.json").exists()
    # a result cut short without its record (as a writer killed half-way would leave it) is not reused
    (killed / "kalman-cv" / "Beta.txt").write_text("1,1,16,16\n" * 10)
    (killed / "kalman-cv" / "Beta.txt.part").write_text("1,1,16")
    # run again, and beside it (into a folder of its own) the uninterrupted run
    full = tmp_path / "full"
    started = [subprocess.Popen([sys.executable, "-m", "vidtrack", "eval", *command, *quiet, "--out", str(folder)],
                                cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
               for quiet, folder in (([], killed), (["-q"], full))]
    (_, again), (_, uninterrupted) = (process.communicate(timeout=300) for process in started)
    assert started[0].returncode == 0, again
    assert "Alpha: reused" in again and "Beta: reused" not in again
    assert started[1].returncode == 0, uninterrupted
    assert _summary(killed) == _summary(full)
    for name in ("Alpha", "Beta"):
        assert (killed / "kalman-cv" / f"{name}.txt").read_text() == (full / "kalman-cv" / f"{name}.txt").read_text()
