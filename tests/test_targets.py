"""Several targets: one tracker per target on the shared frame, IDs that stay on their objects.

The crossing clip (``tests/crossing_clip.py``): three look-alike objects whose
paths cross.  Identities are scored two ways: here, by which ground-truth
object each target's box overlaps most, and by TrackEval (HOTA, IDF1, MOTA)
in its own venv (``make trackeval-env``; ``VIDTRACK_TRACKEVAL`` names its
python, set by ``make test``).
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import vidtrack
from vidtrack.cli import main
from vidtrack.cli.init_boxes import read_init_boxes
from vidtrack.errors import UsageError
from vidtrack.recipes import build_tracker
from vidtrack.run import run_targets
from vidtrack.sinks.files import BoxesSink, CsvLogSink
from vidtrack.sources import open_source
from vidtrack.targets import InteractionConfig, MultiTargetTracker, box_iou, resolve_measurements
from vidtrack.types import Box, Frame, TrackState

sys.path.insert(0, str(Path(__file__).parent))
from crossing_clip import object_boxes, write_clip  # noqa: E402

SCORER = Path(__file__).parent / "trackeval_score.py"
SEED = 0


def read_mot(path: Path) -> dict[int, dict[int, Box]]:
    """ID -> frame (0-based) -> box of a MOT Challenge file."""
    tracks: dict[int, dict[int, Box]] = {}
    for line in path.read_text().splitlines():
        values = [float(v) for v in line.split(",")]
        tracks.setdefault(int(values[1]), {})[int(values[0]) - 1] = Box(*values[2:6])
    return tracks


def on_own_object(tracks: dict[int, dict[int, Box]], truth: dict[int, np.ndarray]) -> dict[int, float]:
    """ID -> fraction of frames whose box overlaps its own object more than any other (and at all)."""
    share = {}
    for target, boxes in tracks.items():
        hits = 0
        for frame, box in boxes.items():
            ious = {j: box_iou(box, Box(*truth[j][frame])) for j in truth}
            hits += ious[target] > 0 and ious[target] == max(ious.values())
        share[target] = hits / len(boxes)
    return share


@pytest.fixture(scope="module")
def crossing(tmp_path_factory) -> dict:
    """The crossing clip tracked by the CLI with mil and kalman-cv: MOT boxes and logs."""
    folder = tmp_path_factory.mktemp("crossing")
    paths = write_clip(folder, SEED)
    runs = {}
    for name in ("kalman-cv", "mil"):
        boxes, log = folder / f"{name}.txt", folder / f"{name}.csv"
        assert main([str(paths["clip"]), "--init-boxes", str(paths["boxes"]), "--filter", name,
                     "--boxes", str(boxes), "--log", str(log), "-q"]) == 0
        runs[name] = {"boxes": boxes, "log": log}
    return {"paths": paths, "runs": runs, "truth": object_boxes(SEED)}


# ------------------------------------------------------------- identities


@pytest.mark.parametrize("name", ["kalman-cv", "mil"])
def test_each_id_stays_on_its_object_where_paths_cross(crossing, name):
    tracks = read_mot(crossing["runs"][name]["boxes"])
    assert sorted(tracks) == [1, 2, 3] and all(len(b) == 90 for b in tracks.values())
    share = on_own_object(tracks, crossing["truth"])
    assert min(share.values()) >= 0.9, share


def test_independent_kalman_trackers_lose_identities_where_aware_ones_keep_them(crossing):
    boxes = read_init_boxes(crossing["paths"]["boxes"])
    shares = {}

    def record(tracks: dict[int, dict[int, Box]]):
        return lambda frame, targets: [tracks[i].update({frame.index: s.box}) for i, s in targets.items()]

    for aware in (False, True):
        tracks: dict[int, dict[int, Box]] = {i: {} for i in boxes}
        multi = MultiTargetTracker({i: build_tracker("kalman-cv", seed=0) for i in boxes},
                                   config=InteractionConfig(aware=aware))
        run_targets(multi, open_source(crossing["paths"]["clip"]), boxes, on_frame=record(tracks))
        shares[aware] = on_own_object(tracks, crossing["truth"])
    assert min(shares[False].values()) < 0.7, shares     # one tracker ends on another's object
    assert min(shares[True].values()) >= 0.9, shares


def test_the_log_has_every_target_on_every_frame(crossing):
    rows = list(csv.DictReader(crossing["runs"]["mil"]["log"].open()))
    assert list(rows[0]) == ["frame", "id", "timestamp", "x", "y", "w", "h", "confidence", "status"]
    assert len(rows) == 3 * 90
    assert [(int(r["frame"]), int(r["id"])) for r in rows[:4]] == [(0, 1), (0, 2), (0, 3), (1, 1)]
    assert {r["status"] for r in rows} <= {"tracking", "lost"}


@pytest.mark.skipif(not os.environ.get("VIDTRACK_TRACKEVAL"),
                    reason="VIDTRACK_TRACKEVAL (TrackEval's venv python, `make trackeval-env`) is not set")
@pytest.mark.parametrize("name", ["kalman-cv", "mil"])
def test_trackeval_scores_the_identities(crossing, name):
    done = subprocess.run([os.environ["VIDTRACK_TRACKEVAL"], str(SCORER), str(crossing["paths"]["gt"]),
                           str(crossing["runs"][name]["boxes"])], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    scores = json.loads(done.stdout)
    print(name, scores)
    assert scores["IDF1"] >= 0.9 and scores["IDSW"] <= 1, scores
    assert scores["HOTA"] >= 0.7 and scores["MOTA"] >= 0.8, scores


@pytest.mark.skipif(not os.environ.get("VIDTRACK_TRACKEVAL"),
                    reason="VIDTRACK_TRACKEVAL (TrackEval's venv python, `make trackeval-env`) is not set")
def test_trackeval_scorer_gives_full_marks_to_the_ground_truth(crossing):
    gt = str(crossing["paths"]["gt"])
    done = subprocess.run([os.environ["VIDTRACK_TRACKEVAL"], str(SCORER), gt, gt], capture_output=True, text=True,
                          timeout=120)
    scores = json.loads(done.stdout)
    assert scores["IDF1"] == scores["HOTA"] == scores["MOTA"] == 1.0


# ------------------------------------------------------------- the resolution rules (pure)


def test_a_measurement_pulled_onto_the_neighbour_is_dropped():
    priors = {1: Box(100, 100, 20, 20), 2: Box(116, 100, 20, 20)}
    measured = {1: Box(108, 100, 20, 20), 2: Box(117, 100, 20, 20)}     # 1 moved 8 px (0.4 box) towards 2
    quality = {1: 0.9, 2: 0.9}
    before = dict(measured)
    dropped = resolve_measurements(priors, measured, quality)
    assert set(dropped) == {1} and "target 2" in dropped[1]
    assert measured == before                                             # pure
    assert resolve_measurements(priors, measured, quality, searching={1}) == {}   # a searching target is exempt
    far = {1: Box(100, 100, 20, 20), 2: Box(300, 100, 20, 20)}                    # priors apart: no gate
    assert resolve_measurements(far, {1: Box(108, 100, 20, 20), 2: Box(300, 100, 20, 20)}, quality) == {}


def test_one_object_goes_to_the_target_it_is_nearer():
    priors = {1: Box(100, 100, 20, 20), 2: Box(300, 100, 20, 20)}
    measured = {1: Box(103, 100, 20, 20), 2: Box(104, 100, 20, 20)}     # 2 re-detected 1's object
    dropped = resolve_measurements(priors, measured, {1: 0.5, 2: 0.9}, searching={2})
    assert set(dropped) == {2} and "same object as target 1" in dropped[2]
    tie = resolve_measurements({1: Box(100, 100, 20, 20), 2: Box(100, 300, 20, 20)},
                               {1: Box(100, 200, 20, 20), 2: Box(100, 201, 20, 20)}, {1: 0.4, 2: 0.8},
                               InteractionConfig(tie=10.0), searching={1, 2})
    assert set(tie) == {1}                                                # a tie goes to the better appearance


# ------------------------------------------------------------- the run and its outputs


def test_one_target_is_exactly_the_single_tracker(crossing):
    clip = str(crossing["paths"]["clip"])
    box = Box(*crossing["truth"][2][0])
    single = [s.box for s in vidtrack.track(clip, box, filter="kalman-cv", max_frames=30)]
    several = [states[1].box for states in vidtrack.track(clip, boxes=[box], filter="kalman-cv", max_frames=30)]
    assert single == several


def test_the_api_yields_every_target_and_agrees_with_the_cli(crossing):
    clip = str(crossing["paths"]["clip"])
    boxes = {i: tuple(b.as_array()) for i, b in read_init_boxes(crossing["paths"]["boxes"]).items()}
    states = list(vidtrack.track(clip, boxes=boxes, filter="kalman-cv"))
    assert len(states) == 90 and all(sorted(s) == [1, 2, 3] for s in states)
    assert all(isinstance(s[2], TrackState) for s in states)
    written = read_mot(crossing["runs"]["kalman-cv"]["boxes"])
    for i in (1, 2, 3):
        assert np.allclose([s[i].box.as_array() for s in states],
                           [written[i][f].as_array() for f in range(90)], atol=0.0051)   # 2 decimals written


def test_thread_count_does_not_change_the_boxes(crossing):
    clip, truth = str(crossing["paths"]["clip"]), crossing["truth"]
    boxes = {i: Box(*truth[i][0]) for i in truth}
    results = []
    for workers in (1, 3):
        multi = MultiTargetTracker({i: build_tracker("mil", seed=0) for i in boxes}, workers=workers)
        results.append([])
        run_targets(multi, open_source(clip), boxes, max_frames=25,
                    on_frame=lambda frame, targets: results[-1].append({i: s.box for i, s in targets.items()}))
    assert results[0] == results[1]


def test_two_init_boxes_track_both_and_write_mot_lines(tmp_path):
    paths = write_clip(tmp_path, 1, frames=20, objects=2)
    first = [line.split(",", 1)[1] for line in paths["boxes"].read_text().splitlines()]
    out = tmp_path / "b.txt"
    assert main([str(paths["clip"]), "--init-box", first[0], "--init-box", first[1], "--filter", "kalman-cv",
                 "--boxes", str(out), "-q"]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == 40
    assert [line.split(",")[:2] for line in lines[:3]] == [["1", "1"], ["1", "2"], ["2", "1"]]
    assert all(line.endswith(",-1,-1,-1") and len(line.split(",")) == 10 for line in lines)
    assert lines[0].split(",")[2:6] == first[0].split(",")[:4] or np.allclose(
        [float(v) for v in lines[0].split(",")[2:6]], [float(v) for v in first[0].split(",")])


def test_init_boxes_file_keeps_its_ids(tmp_path):
    path = tmp_path / "boxes.txt"
    path.write_text("# id,x,y,w,h\n7, 10, 10, 20, 20\n\n3\t40\t40\t20\t20\n")
    assert list(read_init_boxes(path)) == [3, 7]
    assert read_init_boxes(path)[7] == Box(10, 10, 20, 20)


def test_api_rejects_bad_boxes():
    with pytest.raises(UsageError, match="either box"):
        vidtrack.track([], (1, 1, 5, 5), boxes=[(1, 1, 5, 5)])
    with pytest.raises(UsageError, match="positive ints"):
        vidtrack.track([], boxes={0: (1, 1, 5, 5)})
    with pytest.raises(UsageError, match="target 2"):
        vidtrack.track([], boxes=[(1, 1, 5, 5), (1, 1, 0, 5)])


class _Source(list):
    """Frames with a ``missing`` set, as a source that could not decode some of them."""

    missing = {3}


def test_an_undecodable_frame_is_predicted_through_by_every_target(tmp_path):
    paths = write_clip(tmp_path, 2, frames=8, objects=2)
    frames = _Source(open_source(paths["clip"]))
    truth = object_boxes(2, frames=8, objects=2)
    boxes = {i: Box(*truth[i][0]) for i in truth}
    seen = {}
    run_targets(MultiTargetTracker({i: build_tracker("kalman-cv", seed=0) for i in boxes}), frames, boxes,
                on_frame=lambda frame, targets: seen.update({frame.index: targets}))
    assert len(seen) == 8
    assert all(seen[3][i].measured is None and seen[3][i].stages == {} for i in boxes)
    assert all(seen[4][i].measured is not None for i in boxes)


class _Fake:
    """A tracker moving its box a pixel a frame, interrupted (Ctrl-C) at frame ``stop``."""

    def __init__(self, stop: int) -> None:
        self.stop = stop

    def initialize(self, frame, box):
        self.box = box
        return TrackState(frame.index, box, 1.0, "tracking")

    def step(self, frame):
        if frame.index == self.stop:
            raise KeyboardInterrupt
        self.box = Box(self.box.x + 1, self.box.y, self.box.w, self.box.h)
        return TrackState(frame.index, self.box, 0.5, "tracking")


def test_ctrl_c_keeps_every_target_of_every_tracked_frame(tmp_path):
    boxes, log = tmp_path / "b.txt", tmp_path / "l.csv"
    frames = [Frame(i, np.zeros((40, 60, 3), np.uint8), timestamp=i / 25) for i in range(30)]
    multi = MultiTargetTracker({1: _Fake(99), 2: _Fake(12)}, config=InteractionConfig(aware=False), workers=1)
    result = run_targets(multi, frames, {1: Box(1, 1, 9, 9), 2: Box(20, 20, 9, 9)},
                         [BoxesSink(boxes), CsvLogSink(log)])
    assert result.interrupted and result.frames == 12
    assert len(boxes.read_text().splitlines()) == 24
    rows = list(csv.DictReader(log.open()))
    assert len(rows) == 24 and rows[-1]["frame"] == "11" and rows[-1]["timestamp"] == "0.440000"


def test_rerun_has_one_subtree_per_target(tmp_path):
    pytest.importorskip("rerun")
    from rerun_reader import read_recording

    from vidtrack.sinks.rerun import RerunSink

    path = tmp_path / "r.rrd"
    sink = RerunSink(path, filter_name="fake")
    for i in range(4):
        sink.write(Frame(i, np.zeros((40, 60, 3), np.uint8)),
                   {2: TrackState(i, Box(1 + i, 1, 9, 9), 1.0, "tracking"),
                    5: TrackState(i, Box(30, 20, 9, 9), 0.2, "lost" if i > 1 else "tracking")})
    sink.close()
    frames = read_recording(path)
    assert frames["video/frame"] == [0, 1, 2, 3]
    for target in (2, 5):
        assert frames[f"targets/{target}/boxes/estimate"] == [0, 1, 2, 3]
        assert frames[f"targets/{target}/filter/confidence"] == [0, 1, 2, 3]
    assert frames["targets/5/log/status"] == [0, 2] and frames["targets/2/log/status"] == [0]


def test_bench_times_each_count_of_targets(tmp_path, capsys):
    paths = write_clip(tmp_path, 0, frames=6, objects=2)
    assert main(["bench", str(paths["clip"]), "--init-boxes", str(paths["boxes"]), "--filter", "kalman-cv",
                 "--targets", "1,2", "--max-frames", "6"]) == 0
    table = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in table[2:]]
    assert [r[0] for r in rows] == ["1", "2"] and all(r[1] == "5" for r in rows)
    assert float(rows[0][-1]) == 1.0 and float(rows[1][3]) > 0


def test_sigterm_with_several_targets_finishes_every_output(tmp_path):
    paths = write_clip(tmp_path, 0, frames=400, objects=2)
    out = {name: tmp_path / name for name in ("b.txt", "l.csv", "r.rrd")}
    process = subprocess.Popen([sys.executable, "-m", "vidtrack", str(paths["clip"]), "--init-boxes",
                                str(paths["boxes"]), "--filter", "mil", "-q", "--boxes", str(out["b.txt"]),
                                "--log", str(out["l.csv"]), "--rerun", str(out["r.rrd"])],
                               cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while (not out["b.txt"].exists() or len(out["b.txt"].read_text().splitlines()) < 40) \
            and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 143, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    tracked = int(re.search(r"interrupted after (\d+) frames", lines[0]).group(1))
    assert 20 <= tracked < 400
    boxes = out["b.txt"].read_text().splitlines()
    assert len(boxes) == 2 * tracked and all(len(line.split(",")) == 10 for line in boxes)
    assert len(out["l.csv"].read_text().splitlines()) == 2 * tracked + 1

    pytest.importorskip("rerun")
    from rerun_reader import read_recording

    recorded = read_recording(out["r.rrd"])
    assert recorded["video/frame"] == recorded["targets/2/boxes/estimate"] == list(range(tracked))
