"""scripts/tune_sweep.py: the table of a sweep, its groups of sequences, and what it refuses."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import REPO
from vidtrack.eval.synthetic import write_sequence

SCRIPT = REPO / "scripts" / "tune_sweep.py"


def sweep(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *argv], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def two_walkers(tmp_path_factory):
    """Two short sequences: one the mean-shift tracker follows, one whose target runs fast."""
    root = tmp_path_factory.mktemp("sweep")
    write_sequence(root / "Slow", frames=20, size=(160, 120), box=(30, 40, 24, 28), velocity=(1.0, 0.5))
    write_sequence(root / "Fast", frames=20, size=(160, 120), box=(20, 40, 24, 28), velocity=(5.0, 1.0), seed=1)
    return root


def group_rows(stdout: str, group: str) -> list[str]:
    """The rows of the table printed for ``group``."""
    lines = stdout.splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith(f"{group} ("))
    return [line for line in lines[start + 1:] if line.startswith("| `")][:2]


def cells(row: str) -> list[float]:
    """The numbers of a table row (its first cell, the configuration, left out)."""
    return [float(c.strip().strip("*")) for c in row.split("|")[2:-1]]


def test_a_group_table_holds_the_mean_over_its_sequences_alone(two_walkers, tmp_path):
    out = tmp_path / "sweep.json"
    done = sweep(str(two_walkers), "--filter", "ms", "--sequences", "Slow,Fast", "--seeds", "0,1", "--jobs", "1",
                 "--config", "", "--config", "bins=8", "--group", "slow=Slow", "--group", "both=Slow, Fast",
                 "--json", str(out))
    assert done.returncode == 0, done.stderr
    table = json.loads(out.read_text())
    for group, members in (("slow", ["Slow"]), ("both", ["Slow", "Fast"])):
        rows = group_rows(done.stdout, group)
        assert len(rows) == 2
        for row, config in zip(rows, table):
            values = cells(row)
            per_seed = [sum(config["auc"][m][s] for m in members) / len(members) for s in ("0", "1")]
            assert values[:2] == pytest.approx(per_seed, abs=5e-4)
            assert values[2] == pytest.approx(sum(per_seed) / 2, abs=5e-4)
    slow, both = (cells(group_rows(done.stdout, group)[0]) for group in ("slow", "both"))
    assert slow != both   # the groups differ: the fast target is followed worse


@pytest.mark.parametrize("argv, message", [
    (["--group", "slow=Slow,Dancer"], "Dancer not among the swept sequences"),
    (["--group", "slow"], "expected NAME=SEQUENCE"),
    (["--group", "=Slow"], "expected NAME=SEQUENCE"),
    (["--group", "slow="], "expected NAME=SEQUENCE"),
    (["--group", "slow=Slow,Slow"], "named twice"),
    (["--group", "g=Slow", "--group", "g=Fast"], "share a name"),
    (["--seeds", "0,x"], "expected integers"),
    (["--config", "no_such_option=1"], "no_such_option"),
    (["--sequences", "Slow,Dog"], "validate split"),
])
def test_bad_input_stops_the_sweep_before_it_runs_with_one_line(two_walkers, argv, message):
    done = sweep(str(two_walkers), "--filter", "ms", "--sequences", "Slow,Fast", *argv)
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.splitlines()) == 1 and message in done.stderr, done.stderr


def summary_rows(stdout: str) -> list[str]:
    """The rows of the last table, the means per folder."""
    lines = stdout.splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith("Mean AUC over the seeds, per folder"))
    return [line for line in lines[start + 1:] if line.startswith("| `")]


def test_several_folders_are_swept_alike_and_summed_up_per_folder(two_walkers, tmp_path):
    faster = tmp_path / "faster"   # the same sequence names, the targets faster
    write_sequence(faster / "Slow", frames=20, size=(160, 120), box=(30, 40, 24, 28), velocity=(2.0, 1.0))
    write_sequence(faster / "Fast", frames=20, size=(160, 120), box=(20, 40, 24, 28), velocity=(6.0, 1.0), seed=1)
    out = tmp_path / "sweep.json"
    done = sweep(str(two_walkers), str(faster), "--filter", "ms", "--sequences", "Slow,Fast", "--seeds", "0,1",
                 "--jobs", "1", "--config", "", "--config", "bins=8", "--json", str(out))
    assert done.returncode == 0, done.stderr
    table = json.loads(out.read_text())
    assert [(e["dataset"], e["settings"]) for e in table] == [
        (str(two_walkers), {}), (str(two_walkers), {"bins": "8"}), (str(faster), {}), (str(faster), {"bins": "8"})]
    # each folder's own table, headed by its path, holds its entries' means per seed
    for folder in (two_walkers, faster):
        lines = done.stdout.splitlines()
        start = lines.index(f"{folder}:")
        rows = [line for line in lines[start + 1:] if line.startswith("| `")][:2]
        for row, entry in zip(rows, [e for e in table if e["dataset"] == str(folder)]):
            per_seed = [sum(entry["auc"][n][s] for n in ("Slow", "Fast")) / 2 for s in ("0", "1")]
            assert [float(c) for c in row.split("|")[2:4]] == pytest.approx(per_seed, abs=5e-4)
    rows = summary_rows(done.stdout)
    assert len(rows) == 2
    for i, row in enumerate(rows):
        per_folder = [sum(sum(e["auc"][n].values()) for n in ("Slow", "Fast")) / 4 for e in table[i::2]]
        assert cells(row) == pytest.approx(per_folder + [sum(per_folder) / 2], abs=5e-4)
    assert cells(rows[0])[0] != cells(rows[0])[1]   # the faster copy is followed differently


def test_a_folder_without_a_swept_sequence_stops_the_sweep_with_one_line(two_walkers, tmp_path):
    partial = tmp_path / "partial"
    write_sequence(partial / "Slow", frames=20, size=(160, 120), box=(30, 40, 24, 28), velocity=(1.0, 0.5))
    done = sweep(str(two_walkers), str(partial), "--filter", "ms", "--sequences", "Slow,Fast")
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.splitlines()) == 1 and "Fast" in done.stderr and str(partial) in done.stderr, done.stderr
