"""``--subset`` (the benchmarks' published lists) and ``--sequences`` with names or a list.txt."""

from __future__ import annotations

import json

import pytest

from layout_miniatures import SEQUENCES, build_got10k, build_lasot, build_otb
from vidtrack.cli import main as vidtrack_main
from vidtrack.cli.eval import LAYOUT_NAMES, SUBSET_NAMES
from vidtrack.eval.datasets import LAYOUTS, read_dataset
from vidtrack.eval.subsets import LASOT_TEST, SUBSETS

TWO_TARGETS = {"Jogging", "Skating2"}


def test_command_line_choices_are_the_tables():
    assert SUBSET_NAMES == tuple(SUBSETS) and set(LAYOUT_NAMES) == set(LAYOUTS)


@pytest.mark.parametrize("subset, folders, sequences", [
    ("otb2013", 50, 51), ("otb50", 49, 50), ("otb100", 98, 100), ("lasot-test", 280, 280)])
def test_published_list_sizes(subset, folders, sequences):
    names = SUBSETS[subset]
    assert len(names) == len(set(names)) == folders
    assert folders + len(TWO_TARGETS & set(names)) == sequences


def test_lasot_test_is_four_per_class_of_seventy():
    classes = {}
    for name in LASOT_TEST:
        kind, number = name.rsplit("-", 1)
        classes.setdefault(kind, set()).add(int(number))
    assert len(classes) == 70 and all(len(numbers) == 4 for numbers in classes.values())
    assert {"airplane-1", "person-1", "volleyball-19", "rubicCube-14"} <= set(LASOT_TEST)


def test_otb2013_and_50_are_subsets_of_100():
    assert set(SUBSETS["otb2013"]) - set(SUBSETS["otb100"]) == set()
    assert set(SUBSETS["otb50"]) < set(SUBSETS["otb100"])


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_subset_reads_its_sequences_and_reports_the_missing(tmp_path):
    data = build_otb(tmp_path)
    reading = read_dataset(data, subset="otb2013")
    assert [s.name for s in reading.sequences] == ["David", "Jogging-1", "Jogging-2"]
    assert len(reading.errors) == 48 and "Basketball" in reading.errors
    assert reading.errors["Basketball"] == f"sequence Basketball: not in {data} (a sequence of the subset otb2013)"
    reading = read_dataset(data, subset="otb100")
    assert len(reading.sequences) == 6 and len(reading.errors) == 98 - 5
    lasot = build_lasot(tmp_path)
    reading = read_dataset(lasot, subset="lasot-test")
    assert [s.name for s in reading.sequences] == ["person-1"] and len(reading.errors) == 279


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_a_two_target_folder_name_selects_both_targets(tmp_path):
    data = build_otb(tmp_path)
    reading = read_dataset(data, ["jogging", "Board"])
    assert [s.name for s in reading.sequences] == ["Jogging-1", "Jogging-2", "Board"] and not reading.errors


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_eval_sequences_from_a_list_file_and_a_subset(tmp_path, capsys):
    data = build_got10k(tmp_path)
    chosen = tmp_path / "mine.txt"
    chosen.write_text("# one sequence\nGOT-10k_Val_000002\n\n")
    out = tmp_path / "out"
    common = ["--filter", "kalman-cv", "--in-process", "--no-plots", "--max-frames", "3", "-q"]
    assert vidtrack_main(["eval", str(data), "--sequences", str(chosen), "--out", str(out), *common]) == 0
    assert set(json.loads((out / "summary.json").read_text())["kalman-cv"]) == {"GOT-10k_Val_000002", "mean"}

    otb = build_otb(tmp_path)
    out = tmp_path / "out-otb"
    assert vidtrack_main(["eval", str(otb), "--subset", "otb2013", "--out", str(out), *common]) == 1
    summary = json.loads((out / "summary.json").read_text())["kalman-cv"]
    scored = {name for name, row in summary.items() if "error" not in row}
    assert scored == {"David", "Jogging-1", "Jogging-2", "mean"}
    missing = {name: row["error"] for name, row in summary.items() if "error" in row}  # each named with its reason
    assert len(missing) == 48 and missing["Basketball"].startswith("sequence Basketball: not in")
    assert sorted(summary["mean"]["failed"]) == sorted(missing)
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("vidtrack eval: 48 sequence(s) could not be read: sequence Basketball: not in")


@pytest.mark.parametrize("args, message", [
    (["--sequences", "nope.txt"], "--sequences: no such file: nope.txt"),
    (["--sequences", "A", "--subset", "otb100"], "give one"),
    (["--subset", "otb7"], "invalid choice"),
])
def test_bad_sequence_choices_are_one_line_exit_2(tmp_path, capsys, args, message):
    from vidtrack.eval.synthetic import write_sequence

    write_sequence(tmp_path / "data" / "Seq", frames=4)
    try:
        code = vidtrack_main(["eval", str(tmp_path / "data"), "--filter", "kalman-cv", "--out",
                              str(tmp_path / "o"), "-q", *args])
    except SystemExit as exc:  # argparse's own choice check
        code = exc.code
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and "\n" not in err
