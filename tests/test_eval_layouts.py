"""Benchmark layouts as downloaded: each reader on a miniature built from the shared sequences, and
``vidtrack eval`` scoring every sequence of each; one unreadable sequence among good ones."""

from __future__ import annotations

import json

import numpy as np
import pytest

from layout_miniatures import (FRAMES, SEQUENCES, build_got10k, build_lasot, build_otb, build_uav123, build_vot,
                               shared)
from vidtrack.cli import main as vidtrack_main
from vidtrack.errors import DatasetError
from vidtrack.eval.datasets import detect_layout, load_dataset, read_dataset
from vidtrack.eval.layouts.vot import region_to_box
from vidtrack.eval.scoring import score_result

pytestmark = pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")


def _by_name(folder, layout=None):
    return {s.name: s for s in load_dataset(folder, layout=layout)}


def test_otb_as_published(tmp_path):
    data = build_otb(tmp_path)
    _, girl_gt = shared("Girl")
    assert detect_layout(data) == "otb"
    seqs = _by_name(data)
    assert sorted(seqs) == ["BlurCar1", "Board", "David", "Human4", "Jogging-1", "Jogging-2"]
    david = seqs["David"]
    assert len(david) == 11 and david.files[0].name == "0300.jpg" and david.files[-1].name == "0310.jpg"
    assert david.eval_range == (0, 11) and david.origin == 1
    jog1, jog2 = seqs["Jogging-1"], seqs["Jogging-2"]
    assert jog1.files == jog2.files and jog1.path == jog2.path
    np.testing.assert_array_equal(jog2.ground_truth[:, 0] - jog1.ground_truth[:, 0], 40)
    np.testing.assert_array_equal(seqs["Human4"].ground_truth, girl_gt)
    assert seqs["Board"].files[0].name == "00001.jpg" and len(seqs["Board"]) == FRAMES
    assert seqs["BlurCar1"].files[0].name == "0247.jpg"
    np.testing.assert_array_equal(seqs["BlurCar1"].ground_truth, girl_gt)
    assert all(s.absent is None and s.occluded is None for s in seqs.values())


def test_lasot_flags(tmp_path):
    data = build_lasot(tmp_path)
    assert detect_layout(data) == "lasot" and detect_layout(data / "person") == "lasot"
    seqs = _by_name(data)
    assert list(seqs) == ["person-1", "person-2"]
    seq = seqs["person-1"]
    assert seq.origin == 1 and seq.layout == "lasot" and len(seq) == FRAMES
    assert np.flatnonzero(seq.occluded).tolist() == [6] and np.flatnonzero(seq.absent).tolist() == [9]
    assert np.flatnonzero(~seq.present).tolist() == [6, 9]
    assert np.flatnonzero(~seq.annotated).tolist() == [6, 9]  # not scored, as LaSOT's toolkit removes them
    assert list(_by_name(data / "person" / "person-2")) == ["person-2"]


def test_lasot_frames_without_a_visible_target_are_not_scored(tmp_path):
    data = build_lasot(tmp_path)
    _, girl_gt = shared("Girl")
    seq = _by_name(data)["person-1"]
    result = girl_gt.copy()
    result[[6, 9], :2] += 200  # far off on the fully occluded (6) and out-of-view (9) frames only
    path = tmp_path / "person-1.txt"
    np.savetxt(path, result, fmt="%g", delimiter=",")
    row = score_result(seq, path, None).metrics
    assert row["precision20"] == 1.0 and row["norm_precision"] == 1.0 and row["center_error"] == 0.0
    assert row["pascal"] == 1.0
    (data / "person/person-1/full_occlusion.txt").write_text(",".join(["0"] * FRAMES) + "\n")
    (data / "person/person-1/out_of_view.txt").write_text(",".join(["0"] * FRAMES) + "\n")
    row = score_result(_by_name(data)["person-1"], path, None).metrics  # no flags: both frames scored
    assert row["precision20"] == pytest.approx(10 / 12) and row["center_error"] > 0


def test_got10k_val_and_test(tmp_path):
    data = build_got10k(tmp_path)
    _, girl_gt = shared("Girl")
    assert detect_layout(data) == "got10k"
    seqs = _by_name(data)
    assert list(seqs) == ["GOT-10k_Val_000001", "GOT-10k_Val_000002"]
    seq = seqs["GOT-10k_Val_000001"]
    assert seq.origin == 0 and len(seq) == FRAMES
    assert np.flatnonzero(seq.absent).tolist() == [8] and np.flatnonzero(seq.occluded).tolist() == [8]
    assert seq.annotated.sum() == FRAMES - 1
    assert seq.to_pixels(seq.ground_truth_box(0)) == seq.ground_truth_box(0)  # 0-based
    (test,) = load_dataset(tmp_path / "got10k" / "test")
    assert len(test) == FRAMES and test.annotated.tolist() == [True] + [False] * (FRAMES - 1)
    np.testing.assert_array_equal(test.ground_truth[0], girl_gt[0] - [1, 1, 0, 0])


def test_uav123_nan_rows(tmp_path):
    root = build_uav123(tmp_path)
    assert detect_layout(root) == "uav123" and detect_layout(root / "UAV123") == "uav123"
    split, seq = load_dataset(root)
    assert split.name == "car16_1" and len(split) == 415 and split.files[-1].name == "000415.jpg"
    assert split.path.name == "car16"
    assert seq.name == "person1" and seq.origin == 1 and len(seq) == FRAMES
    assert np.flatnonzero(seq.absent).tolist() == [4, 5]
    assert np.flatnonzero(~seq.annotated).tolist() == [4, 5]


def test_vot_polygons_become_bounding_rectangles(tmp_path):
    data = build_vot(tmp_path)
    _, girl_gt = shared("Girl")
    assert detect_layout(data) == "vot"
    seqs = _by_name(data)
    assert list(seqs) == ["girl", "girl2"]
    np.testing.assert_array_equal(seqs["girl"].ground_truth, girl_gt - [1, 1, 0, 0])
    np.testing.assert_array_equal(seqs["girl2"].ground_truth, girl_gt - [1, 1, 0, 0])
    assert seqs["girl"].files[0].parent.name == "color" and seqs["girl"].origin == 0
    assert region_to_box([3, 1, 7, 2, 6, 9, 2, 8]) == (2, 1, 5, 8)
    with pytest.raises(ValueError, match="polygon"):
        region_to_box([1, 2, 3, 4, 5])


def test_named_layout_overrides_detection(tmp_path):
    data = build_vot(tmp_path)
    with pytest.raises(DatasetError, match="no otb sequences"):
        load_dataset(data, layout="otb")
    assert len(load_dataset(data, layout="vot")) == 2


def test_one_unreadable_sequence_is_reported_the_others_read(tmp_path):
    data = build_lasot(tmp_path)
    (data / "person/person-2/groundtruth.txt").write_text("1,2,3,4\n")
    reading = read_dataset(data)
    assert [s.name for s in reading.sequences] == ["person-1"]
    assert list(reading.errors) == ["person-2"]
    assert reading.errors["person-2"].startswith("sequence person-2: ")
    assert "groundtruth.txt has 1 rows but img/ holds 12 images" in reading.errors["person-2"]


@pytest.mark.parametrize("build", [build_otb, build_lasot, build_got10k, build_uav123, build_vot])
def test_eval_scores_every_sequence_of_each_layout(tmp_path, build, capsys):
    data = build(tmp_path)
    names = {s.name for s in load_dataset(data)}
    out = tmp_path / "out"
    code = vidtrack_main(["eval", str(data), "--filter", "kalman-cv", "--out", str(out), "--in-process",
                          "--no-plots", "--max-frames", "6", "-q"])
    assert code == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    scored = {name for name in summary["kalman-cv"] if name != "mean"}
    assert scored == names
    for name in names:
        row = summary["kalman-cv"][name]
        assert row.get("error") is None and 0 < row["auc"] <= 1
        assert (out / "kalman-cv" / f"{name}.txt").is_file()


def test_eval_one_bad_sequence_among_good_ones(tmp_path, capsys):
    data = build_vot(tmp_path)
    (data / "girl2/groundtruth.txt").write_text("1,2,3\n" * FRAMES)
    out = tmp_path / "out"
    code = vidtrack_main(["eval", str(data), "--filter", "kalman-cv", "--out", str(out), "--in-process",
                          "--no-plots", "--max-frames", "4"])
    captured = capsys.readouterr()
    err = captured.err
    assert code == 1
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["kalman-cv"]) == ["girl", "girl2", "mean"] and summary["kalman-cv"]["girl"]["auc"] > 0
    bad = summary["kalman-cv"]["girl2"]  # the unreadable sequence is that sequence's error, with the reason
    assert bad["auc"] is None and bad["error"].startswith("sequence girl2: ")
    assert "groundtruth.txt, line 1: expected 4 numbers or a polygon" in bad["error"]
    mean = summary["kalman-cv"]["mean"]
    assert mean["failed"] == ["girl2"] and mean["auc"] == summary["kalman-cv"]["girl"]["auc"]
    assert "FAILED: sequence girl2: " in (out / "summary.md").read_text()
    assert "FAILED: sequence girl2: " in captured.out  # the printed table
    assert not list(out.glob("*.part"))  # written whole through a temporary file
    last = err.strip().splitlines()[-1]
    assert last.startswith("vidtrack eval: 1 sequence(s) could not be read: sequence girl2: ")
    assert "groundtruth.txt, line 1: expected 4 numbers or a polygon" in last
    assert "skipped: sequence girl2: " in err and "Traceback" not in err
