"""Sequence loaders (OTB and MIL layouts), conventions, and one-line errors for bad datasets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vidtrack.cli import main as vidtrack_main
from vidtrack.errors import DatasetError
from vidtrack.eval.datasets import load_dataset, load_sequence, parse_boxes
from vidtrack.eval.synthetic import write_sequence

SEQUENCES = Path(__file__).resolve().parents[2] / "shared/data/sequences"


def test_parse_boxes_accepts_comma_tab_space_and_rejects_garbage():
    text = "1,2,3,4\n5\t6\t7\t8\r\n9 10 11 12\n\n"
    np.testing.assert_array_equal(parse_boxes(text), [[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12]])
    with pytest.raises(DatasetError, match="line 2"):
        parse_boxes("1,2,3,4\n1,2,3\n")
    with pytest.raises(DatasetError, match="line 1"):
        parse_boxes("a,b,c,d\n")


def test_otb_layout_is_one_based(tmp_path):
    truth = write_sequence(tmp_path / "Toy", layout="otb", frames=6, separator="\t")
    seq = load_sequence(tmp_path / "Toy")
    assert (seq.origin, seq.layout, len(seq), seq.run_range, seq.init_index) == (1, "otb", 6, (0, 6), 0)
    init = seq.to_pixels(seq.ground_truth_box(0))
    assert (init.x, init.y) == tuple(truth[0, :2])
    assert seq.from_pixels(init) == seq.ground_truth_box(0)


def test_mil_layout_more_images_than_rows(tmp_path):
    # 12 images numbered 0..11, ground truth and MIL range for 1..11 only (like MIL sylv)
    write_sequence(tmp_path / "toy", layout="mil", frames=12, first_number=0, annotate_every=5,
                   frames_range=(1, 11))
    gt_path = tmp_path / "toy" / "toy_gt.txt"
    gt_path.write_text("".join(gt_path.read_text().splitlines(keepends=True)[1:]))
    seq = load_sequence(tmp_path / "toy")
    assert seq.origin == 0 and seq.layout == "mil"
    assert [p.name for p in seq.files][:2] == ["img00001.png", "img00002.png"] and len(seq) == 11
    assert seq.run_range == (0, 11)
    assert seq.annotated.tolist() == [k % 5 == 0 for k in range(1, 12)]
    assert seq.init_index == 4  # img00005, the first annotated row


def test_mil_frames_range_inside_the_rows(tmp_path):
    # one row per image (like MIL faceocc2), but the paper ran on frames 3..10 only
    write_sequence(tmp_path / "toy", layout="mil", frames=12, first_number=0, annotate_every=2,
                   frames_range=(3, 10))
    seq = load_sequence(tmp_path / "toy")
    assert len(seq) == 12 and seq.run_range == (3, 11)
    assert seq.init_index == 4 and seq.eval_range == (4, 11)  # first annotated row inside the range


def test_dataset_path_may_be_a_single_sequence(tmp_path):
    write_sequence(tmp_path / "Only", frames=3)
    assert [s.name for s in load_dataset(tmp_path / "Only")] == ["Only"]


@pytest.mark.parametrize("problem, message", [
    ("empty", "no sequences"),
    ("no_gt", "no ground truth"),
    ("rows", "has 4 rows but img/ holds 5 images"),
    ("unknown", "unknown sequence 'Nope'; sequences in"),
    ("nothing_annotated", "no annotated"),
])
def test_bad_datasets_give_one_line_exit_2(tmp_path, capsys, problem, message):
    data = tmp_path / "data"
    data.mkdir()
    args = ["eval", str(data), "--filter", "kalman-cv", "--out", str(tmp_path / "out"), "-q"]
    if problem != "empty":
        write_sequence(data / "Seq", frames=5)
    if problem == "no_gt":
        (data / "Seq" / "groundtruth_rect.txt").unlink()
    elif problem == "rows":
        (data / "Seq" / "groundtruth_rect.txt").write_text("1,1,5,5\n" * 4)
    elif problem == "unknown":
        args += ["--sequences", "Nope"]
    elif problem == "nothing_annotated":
        (data / "Seq" / "groundtruth_rect.txt").write_text("0,0,0,0\n" * 5)
    assert vidtrack_main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_unknown_filter_lists_valid_ones(tmp_path, capsys):
    write_sequence(tmp_path / "Seq", frames=3)
    assert vidtrack_main(["eval", str(tmp_path), "--filter", "kalman-cv,nosuch", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown filter 'nosuch'" in err and "kalman-cv" in err and "\n" not in err


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_shared_sequences_conventions():
    seqs = {s.name: s for s in load_dataset(SEQUENCES)}
    assert {"Girl", "FaceOcc1", "FaceOcc2", "David"} <= set(seqs)
    assert seqs["Girl"].origin == 1 and seqs["FaceOcc1"].origin == 1 and seqs["David"].origin == 0
    face2 = seqs["FaceOcc2"]
    # MIL range 8..819 = rows 5..816 (1-based); first annotated row inside it is row 6 (img00009)
    assert face2.run_range == (4, 816) and face2.files[4].name == "img00008.png"
    assert face2.init_index == 5 and face2.files[5].name == "img00009.png"
    assert seqs["David"].annotated.sum() == 93
