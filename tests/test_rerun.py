"""The Rerun sink: recordings are complete, hold the documented entity paths and every frame.

Recordings are read back two independent ways: the installed ``rerun`` CLI
(``rerun rrd verify`` / ``rerun rrd stats``) and :func:`rerun_reader.read_recording`
(per-entity frame indices).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("rerun")

from vidtrack.cli import main as cli_main
from vidtrack.errors import OutputError, UsageError
from vidtrack.run import run_tracker
from vidtrack.sinks.rerun import RerunSink
from vidtrack.sinks.stage_images import (colormap_lut, display_image, float_to_uint8, labels_for_segmentation,
                                         nearest_resize, point_display, region_transform, stage_kind)
from vidtrack.types import Box, Frame, TrackState

from rerun_reader import read_recording  # noqa: E402  (tests/: importable once rerun is)

SEQUENCES = Path(__file__).resolve().parents[2] / "shared/data/sequences"
RERUN_CLI = Path(sys.executable).parent / "rerun"

N_FRAMES = 12
LOST_FRAMES = range(4, 7)        # lost on 4, 5, 6: "lost" at 4, "re-acquired" at 7
NO_MEASUREMENT = 5               # frame 5 has no measured box and no stages
GROUND_TRUTH = {0: Box(60, 50, 60, 50), 5: Box(66, 50, 60, 50), 10: Box(70, 50, 60, 50),
                3: Box(0, 0, 0, 0)}   # all zero: not annotated


def rerun_cli(*args: str) -> subprocess.CompletedProcess:
    if not RERUN_CLI.exists():
        pytest.skip("the rerun CLI is not installed beside the interpreter")
    return subprocess.run([str(RERUN_CLI), *args], capture_output=True, text=True, timeout=120)


def stats_entities(path: Path) -> set[str]:
    """Entity paths under vidtrack's roots that ``rerun rrd stats`` lists (blueprint ones left out)."""
    out = rerun_cli("rrd", "stats", str(path))
    assert out.returncode == 0, out.stderr
    section = out.stdout.split("Num chunks per entity", 1)[1].split("\n\n", 1)[0]
    found = set(re.findall(r"^/(\S+): \d+", section, flags=re.M))
    return {e for e in found if e.startswith(("video/", "targets/"))}


def verify(path: Path) -> None:
    out = rerun_cli("rrd", "verify", str(path))
    assert out.returncode == 0, out.stdout + out.stderr


def hand_states(rng: np.random.Generator):
    """Frames and TrackStates with every kind of stage, built by hand (no filter needed)."""
    for i in range(N_FRAMES):
        image = np.full((120, 160, 3), 80, np.uint8)
        cv2.rectangle(image, (30 + i, 25), (90 + i, 75), (0, 0, 255), -1)
        region = Box(10.0 + i, 5.0, 100.0, 90.0)
        stages = {}
        if 0 < i != NO_MEASUREMENT:
            stages = {
                "superpixels": rng.integers(0, 40, (45, 50)),
                "svm_scores": rng.normal(size=(45, 50)).astype(np.float32),
                "inliers": rng.random((45, 50)) > 0.5,
                "score_map": rng.random((30, 40)),
                "backprojection": rng.random((45, 50)).astype(np.float32),
                "detections": np.c_[rng.random((4, 2)) * 150, rng.random(4)],
                "particles": np.c_[rng.random((400, 2)) * 150, rng.random(400)],
                "my stage": rng.random((20, 25)),          # unknown image stage
                "my_points": rng.random((7, 3)) * 100,     # unknown point stage
            }
        state = TrackState(
            index=i, box=Box(30.0 + i, 25.0, 60.0, 50.0), confidence=0.3 if i in LOST_FRAMES else 0.9,
            status="lost" if i in LOST_FRAMES else "tracking",
            predicted=Box(29.0 + i, 25.0, 60.0, 50.0) if i else None,
            measured=Box(31.0 + i, 25.0, 60.0, 50.0) if 0 < i != NO_MEASUREMENT else None,
            search_region=region if 0 < i != NO_MEASUREMENT else None,
            stages=stages,
            scalars={"confidence": 0.9, "innovation": float(i), "covariance_trace": 2.0 + i, "c_t": 0.5},
        )
        yield Frame(i, image), state


@pytest.fixture(scope="module")
def hand_recording(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rerun") / "sub" / "hand.rrd"   # missing folder is created
    # batch_frames=5: rows cross batch boundaries (frames 0-4, 5-9, 10-11 sent at close)
    sink = RerunSink(path, filter_name="hand", ground_truth=GROUND_TRUTH, superpixels_every=5, batch_frames=5)
    for frame, state in hand_states(np.random.default_rng(0)):
        sink.write(frame, {1: state})
    sink.close()
    sink.close()  # idempotent
    return path


def test_recording_verifies_and_lists_every_entity(hand_recording):
    verify(hand_recording)
    expected = {
        "video/frame", "targets/1/boxes/predicted", "targets/1/boxes/measured", "targets/1/boxes/estimate",
        "video/boxes/ground_truth", "targets/1/search_region",
        "targets/1/stages/superpixels", "targets/1/stages/svm_scores", "targets/1/stages/inliers", "targets/1/stages/score_map",
        "targets/1/stages/detections", "targets/1/stages/particles", "targets/1/stages/backprojection", "targets/1/stages/my_stage",
        "targets/1/stages/my_points", "targets/1/filter/confidence", "targets/1/filter/innovation", "targets/1/filter/covariance_trace",
        "targets/1/filter/c_t", "targets/1/log/status",
    }
    assert stats_entities(hand_recording) == expected
    assert set(read_recording(hand_recording)) == expected   # the recording store alone: nothing else


def test_recording_holds_every_frame_per_entity(hand_recording):
    frames = read_recording(hand_recording)
    every = list(range(N_FRAMES))
    measured = [i for i in every if 0 < i != NO_MEASUREMENT]
    assert frames["video/frame"] == every
    assert frames["targets/1/boxes/estimate"] == every
    assert frames["targets/1/filter/confidence"] == every
    assert frames["targets/1/filter/innovation"] == every
    assert frames["targets/1/boxes/predicted"] == every[1:]
    assert frames["targets/1/boxes/measured"] == measured
    assert frames["targets/1/search_region"] == measured
    assert frames["video/boxes/ground_truth"] == [0, 5, 10]      # annotated frames only
    for name in ("svm_scores", "inliers", "score_map", "backprojection", "particles", "detections",
                 "my_stage", "my_points"):
        assert frames[f"targets/1/stages/{name}"] == measured, name
    assert frames["targets/1/stages/superpixels"] == [10]                  # every 5th frame (5 had none)
    assert frames["targets/1/log/status"] == [0, LOST_FRAMES[0], LOST_FRAMES[-1] + 1]


def test_status_changes_are_a_text_log(hand_recording):
    out = rerun_cli("rrd", "print", "-vvv", "--entity", "/targets/1/log/status", str(hand_recording))
    assert out.returncode == 0, out.stderr
    assert "lost" in out.stdout and "re-acquired" in out.stdout


def test_default_blueprint_shows_frame_stages_and_plots(hand_recording):
    out = rerun_cli("rrd", "print", "-vvv", str(hand_recording))
    assert out.returncode == 0, out.stderr
    for name in ("superpixels", "svm_scores", "inliers", "score_map", "backprojection", "my_stage"):
        assert re.search(rf"\+ targets/1/stages/{name}[,\]]", out.stdout), name   # one overlay view per image stage
    assert "+ targets/1/stages/particles" in out.stdout and "+ video/**" in out.stdout   # the frame view
    assert "TimeSeries" in out.stdout                                     # the plots view class


def test_two_recordings_in_one_process_are_separate(tmp_path):
    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    sink_a = RerunSink(a, filter_name="a")
    sink_b = RerunSink(b, filter_name="b")
    image = np.zeros((40, 50, 3), np.uint8)
    for i in range(6):
        sink_a.write(Frame(i, image), {1: TrackState(i, Box(5, 5, 10, 10), 1.0, "tracking")})
        if i < 3:
            sink_b.write(Frame(i, image), {1: TrackState(i, Box(5, 5, 10, 10), 1.0, "tracking")})
    sink_b.close()
    verify(b)      # b is complete while a is still open
    sink_a.close()
    verify(a)
    assert read_recording(a)["video/frame"] == list(range(6))
    assert read_recording(b)["video/frame"] == list(range(3))


def test_unwritable_path_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match="folder"):
        RerunSink(tmp_path, filter_name="x")
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError) as err:
        RerunSink(blocker / "out.rrd", filter_name="x")
    assert "\n" not in str(err.value)
    with pytest.raises(UsageError):
        RerunSink(None, filter_name="x")


class _InterruptedTracker:
    """A tracker that moves its box one pixel a frame and is interrupted (Ctrl-C) at ``stop``."""

    def __init__(self, stop: int) -> None:
        self.stop = stop

    def initialize(self, frame, box):
        self.box = box
        return TrackState(frame.index, box, 1.0, "tracking", measured=box)

    def step(self, frame):
        if frame.index == self.stop:
            raise KeyboardInterrupt
        self.box = Box(self.box.x + 1, self.box.y, self.box.w, self.box.h)
        return TrackState(frame.index, self.box, 0.8, "tracking", predicted=self.box,
                          search_region=self.box.scaled(2.0),
                          stages={"backprojection": np.random.default_rng(frame.index).random((20, 20))})


def test_ctrl_c_mid_run_leaves_a_complete_recording(tmp_path):
    path = tmp_path / "interrupted.rrd"
    frames = (Frame(i, np.full((60, 80, 3), 10 * i, np.uint8)) for i in range(50))
    sink = RerunSink(path, filter_name="fake")
    result = run_tracker(_InterruptedTracker(stop=17), frames, Box(10, 10, 20, 20), [sink])
    assert result.interrupted and result.frames == 17
    verify(path)   # while ``sink`` is alive: close() itself, not garbage collection, completed the file
    assert read_recording(path)["video/frame"] == list(range(17))


def test_ctrl_c_inside_the_sink_leaves_no_half_frame(tmp_path, monkeypatch):
    import vidtrack.sinks.rerun as sink_module

    real = sink_module.display_image

    def interrupt_on_frame_9(image, **kw):
        if image.shape == (20, 20) and image[0, 0] == 9:
            raise KeyboardInterrupt     # Ctrl-C while the sink encodes frame 9's stage
        return real(image, **kw)

    class Tracker(_InterruptedTracker):
        def step(self, frame):
            state = super().step(frame)
            return TrackState(state.index, state.box, 0.8, "tracking", search_region=state.search_region,
                              stages={"backprojection": np.full((20, 20), frame.index, np.uint8)})

    monkeypatch.setattr(sink_module, "display_image", interrupt_on_frame_9)
    path = tmp_path / "interrupted.rrd"
    sink = RerunSink(path, filter_name="fake")
    frames = (Frame(i, np.full((60, 80, 3), 10 * i, np.uint8)) for i in range(50))
    result = run_tracker(Tracker(stop=99), frames, Box(10, 10, 20, 20), [sink])
    assert result.interrupted and result.frames == 9
    verify(path)
    recorded = read_recording(path)
    assert recorded["video/frame"] == list(range(9))          # frame 9 was not half logged
    assert recorded["targets/1/boxes/estimate"] == list(range(9))
    assert recorded["targets/1/stages/backprojection"] == list(range(1, 9))


def _write_synthetic_video(folder: Path, n: int) -> None:
    folder.mkdir()
    for i in range(n):
        image = np.full((120, 160, 3), 40, np.uint8)
        cv2.circle(image, (40 + 3 * i, 60), 14, (30, 200, 240), -1)
        cv2.imwrite(str(folder / f"{i:04d}.png"), image)


@pytest.mark.parametrize("name", ["ms", "kalman-cv"])
def test_cli_writes_a_recording(tmp_path, name):
    _write_synthetic_video(tmp_path / "img", 10)
    out = tmp_path / f"{name}.rrd"
    assert cli_main([str(tmp_path / "img"), "--init-box", "26,46,28,28", "--filter", name,
                     "--rerun", str(out), "-q"]) == 0
    verify(out)
    frames = read_recording(out)
    assert frames["video/frame"] == list(range(10))
    assert frames["targets/1/stages/backprojection"] == list(range(1, 10))   # mean-shift based filters
    assert "video/boxes/ground_truth" not in frames                # eval only


def test_cli_rerun_to_unwritable_path_is_one_line(tmp_path, capsys):
    _write_synthetic_video(tmp_path / "img", 2)
    assert cli_main([str(tmp_path / "img"), "--init-box", "26,46,28,28", "--filter", "ms",
                     "--rerun", str(tmp_path), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vidtrack: error:") and "\n" not in err


@pytest.mark.skipif(not (SEQUENCES / "David/img").is_dir(), reason="shared sequences missing")
def test_size_budget_on_a_real_320x240_sequence(tmp_path):
    out = tmp_path / "david.rrd"
    n = 40
    assert cli_main([str(SEQUENCES / "David/img"), "--init-box", "122,58,75,97", "--filter", "kalman-cv",
                     "--rerun", str(out), "--max-frames", str(n), "-q"]) == 0
    verify(out)
    assert read_recording(out)["video/frame"] == list(range(n))
    assert out.stat().st_size / n < 60 * 1024


#: Entities each paper filter must show (its own stages and scalars), beyond those every filter shows.
FILTER_ENTITIES = {
    "mil": {"targets/1/stages/superpixels", "targets/1/stages/svm_scores", "targets/1/stages/inliers", "targets/1/filter/inlier_count",
            "targets/1/filter/svm_margin"},
    "nh": {"targets/1/stages/score_map", "targets/1/stages/particles", "targets/1/filter/c_t", "targets/1/filter/live_actions"},
    "svk": {"targets/1/filter/F_00", "targets/1/filter/Q_00", "targets/1/filter/innovation"},
    "cbt": {"targets/1/stages/score_map", "targets/1/stages/detections"},
}
COMMON_ENTITIES = {"video/frame", "targets/1/boxes/estimate", "targets/1/boxes/predicted", "targets/1/search_region",
                   "targets/1/filter/confidence", "targets/1/log/status"}


@pytest.mark.skipif(not (SEQUENCES / "David/img").is_dir(), reason="shared sequences missing")
@pytest.mark.parametrize("name", sorted(FILTER_ENTITIES))
def test_paper_filters_record_their_stages(tmp_path, name):
    from vidtrack.recipes import registry

    if name not in registry():
        pytest.skip(f"{name} is not registered in this build")
    out = tmp_path / f"{name}.rrd"
    n = 12   # superpixels are logged on frames 5 and 10
    assert cli_main([str(SEQUENCES / "David/img"), "--init-box", "122,58,75,97", "--filter", name,
                     "--rerun", str(out), "--max-frames", str(n), "-q"]) == 0
    verify(out)
    missing = (COMMON_ENTITIES | FILTER_ENTITIES[name]) - stats_entities(out)
    assert not missing, missing
    assert read_recording(out)["video/frame"] == list(range(n))


# ---------------------------------------------------------------- pure helpers


def test_float_to_uint8_ranges():
    assert float_to_uint8(np.array([[0.0, 1.0]])).tolist() == [[0, 255]]
    assert float_to_uint8(np.array([[0.0, 0.5]])).tolist() == [[0, 128]]          # [0,1] kept absolute
    assert float_to_uint8(np.array([[-1.0, 0.0, 1.0]])).tolist() == [[0, 128, 255]]
    assert float_to_uint8(np.array([[3.0, 5.0, np.nan]])).tolist() == [[0, 255, 0]]  # stretched
    assert float_to_uint8(np.full((2, 2), np.inf)).tolist() == [[0, 0], [0, 0]]


def test_colormap_lut_matches_opencv():
    image = np.random.default_rng(1).integers(0, 256, (30, 40)).astype(np.uint8)
    assert np.array_equal(cv2.applyColorMap(image, colormap_lut("viridis")),
                          cv2.applyColorMap(image, cv2.COLORMAP_VIRIDIS))


def test_region_transform_maps_array_corners_onto_region():
    region = Box(12.0, 30.0, 80.0, 40.0)
    translation, scale = region_transform(region, (20, 40))     # (h, w)
    far = np.array(translation[:2]) + np.array(scale[:2]) * np.array([40, 20])
    assert translation[:2] == [12.0, 30.0]
    assert far.tolist() == [92.0, 70.0]


def test_point_display_keeps_heaviest_and_grows_radius_with_weight():
    pts = np.array([[0, 0, 0.1], [1, 1, 0.9], [2, 2, 0.4], [3, 3, np.nan], [4, 4, 0.0]])
    pos, radii = point_display(pts, max_points=2, radius_range=(0.5, 4.0))
    assert sorted(pos[:, 0].tolist()) == [1.0, 2.0]
    assert radii[pos[:, 0] == 1.0][0] == pytest.approx(4.0)
    assert radii[pos[:, 0] == 2.0][0] < 4.0
    pos, radii = point_display(pts, max_points=0, radius_range=(0.5, 4.0))
    assert len(pos) == 4 and radii[np.argmin(pts[[0, 1, 2, 4], 2])] == pytest.approx(0.5)


def test_stage_kinds_and_encodings():
    assert stage_kind("superpixels", np.zeros((10, 12), int)) == "labels"
    assert stage_kind("particles", np.zeros((5, 3))) == "points"
    assert stage_kind("particles", np.zeros((0, 3))) == "points"
    assert stage_kind("whatever", np.zeros((5, 3))) == "points"
    assert stage_kind("whatever", np.zeros((10, 12))) == "image"
    assert stage_kind("whatever", np.zeros(4)) is None
    big = np.arange(300 * 200).reshape(300, 200)
    small = nearest_resize(big, 100)
    assert small.shape == (100, 67) and set(np.unique(small)) <= set(np.unique(big))
    seg = labels_for_segmentation(np.array([[-1, 3], [7, 7]]), 64)
    assert seg.dtype == np.uint16 and seg.min() == 1 and seg.tolist() == [[1, 5], [9, 9]]
    data, media, shape = display_image(np.random.default_rng(0).random((300, 150)) > 0.5,
                                       max_side=64, colormap="viridis", jpeg_quality=80)
    assert media == "image/png" and shape == (64, 32)
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert set(np.unique(decoded)) <= {0, 255}
    data, media, shape = display_image(np.random.default_rng(0).random((50, 60)),
                                       max_side=64, colormap="viridis", jpeg_quality=80)
    assert media == "image/jpeg" and shape == (50, 60)
    assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR).shape == (50, 60, 3)
