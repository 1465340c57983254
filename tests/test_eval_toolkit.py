"""Results written in the layout of each benchmark's own toolkit (OUT/toolkit/<layout>/<filter>/)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from layout_miniatures import FRAMES, SEQUENCES, build_got10k, build_otb, build_uav123, build_vot
from vidtrack.cli import main as vidtrack_main
from vidtrack.eval.datasets import load_dataset, read_boxes
from vidtrack.eval.toolkit import frame_times, toolkit_paths

pytestmark = pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")


def _run(data, out, *extra):
    return vidtrack_main(["eval", str(data), "--filter", "kalman-cv", "--out", str(out), "--in-process",
                          "--no-plots", "-q", *extra])


def test_frame_times_spread_the_run_over_its_tracked_rows():
    record = {"tracked": [2, 5], "frames": 3, "track_seconds": 0.3}
    assert frame_times(record, 6) == pytest.approx([0, 0, 0.1, 0.1, 0.1, 0])
    record["frame_seconds"] = [0.2, 0.05, 0.05]  # each tracked row's own time
    assert frame_times(record, 6) == pytest.approx([0, 0, 0.2, 0.05, 0.05, 0])
    with pytest.raises(ValueError, match="vot"):
        toolkit_paths("out", "vot", "f", "s")


def test_got10k_val_and_test_in_the_submission_layout(tmp_path):
    out = tmp_path / "out"
    assert _run(build_got10k(tmp_path), out, "--max-frames", "6") == 0
    assert _run(tmp_path / "got10k" / "test", out) == 0
    base = out / "toolkit" / "got10k" / "kalman-cv"
    assert sorted(p.name for p in base.iterdir()) == ["GOT-10k_Test_000001", "GOT-10k_Val_000001",
                                                      "GOT-10k_Val_000002"]
    for name in ("GOT-10k_Val_000001", "GOT-10k_Test_000001"):
        boxes = np.loadtxt(base / name / f"{name}_001.txt", delimiter=",")
        np.testing.assert_array_equal(boxes, read_boxes(out / "kalman-cv" / f"{name}.txt"))
        times = np.loadtxt(base / name / f"{name}_time.txt")
        assert boxes.shape == (FRAMES, 4) and times.shape == (FRAMES,)
    test = np.loadtxt(base / "GOT-10k_Test_000001" / "GOT-10k_Test_000001_001.txt", delimiter=",")
    (seq,) = load_dataset(tmp_path / "got10k" / "test")
    np.testing.assert_allclose(test[0], seq.ground_truth[0])  # the first row is the given box
    assert np.all(test[1:, 2:] > 0)                           # every later frame tracked
    val_times = np.loadtxt(base / "GOT-10k_Val_000001" / "GOT-10k_Val_000001_time.txt")
    assert np.all(val_times[:6] > 0) and np.all(val_times[6:] == 0)  # --max-frames 6
    record = json.loads((out / "kalman-cv" / "GOT-10k_Val_000001.json").read_text())
    assert val_times[:6] == pytest.approx(record["frame_seconds"], abs=1e-8)  # each frame's own time
    assert len(set(record["frame_seconds"])) > 1                              # not one mean repeated
    assert sum(record["frame_seconds"]) == pytest.approx(record["track_seconds"], rel=0.2)


def test_otb_and_uav123_one_file_per_sequence_vot_none(tmp_path):
    out = tmp_path / "out"
    otb = build_otb(tmp_path)
    assert _run(otb, out, "--sequences", "Jogging,David", "--max-frames", "4") == 0
    folder = out / "toolkit" / "otb" / "kalman-cv"
    assert sorted(p.name for p in folder.iterdir()) == ["David.txt", "Jogging-1.txt", "Jogging-2.txt"]
    np.testing.assert_array_equal(np.loadtxt(folder / "David.txt", delimiter=","),
                                  read_boxes(out / "kalman-cv" / "David.txt"))
    assert _run(build_uav123(tmp_path), out, "--max-frames", "4") == 0
    assert (out / "toolkit" / "uav123" / "kalman-cv" / "person1.txt").is_file()
    assert _run(build_vot(tmp_path), tmp_path / "vot-out", "--max-frames", "4") == 0
    assert not (tmp_path / "vot-out" / "toolkit").exists()
