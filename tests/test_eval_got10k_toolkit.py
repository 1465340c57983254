"""vidtrack's scores agree with the got10k toolkit's (PyPI got10k 0.1.3, in .venv-got10k made by
``make got10k-env``) on the same result files, to 1e-6, for every figure both compute.

Figures compared (vidtrack key <- got10k key): OTB and UAV123 per sequence and overall ``auc`` <-
``success_score``, ``precision20`` <- ``precision_score``, ``pascal`` <- ``success_rate``; GOT-10k
val ``ao`` <- ``ao`` and ``sr50`` <- ``sr``.  got10k 0.1.3 has no LaSOT experiment and no SR0.75.  Its
GOT-10k speed, the mean over frames of 1 / (seconds), is read from the ``<seq>_time.txt`` files vidtrack
writes: it equals that mean of the run records' ``frame_seconds`` (vidtrack's own ``fps`` is frames over
total seconds, another figure).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from layout_miniatures import SEQUENCES, build_got10k, build_otb, build_uav123
from vidtrack.cli import main as vidtrack_main

REPO = Path(__file__).resolve().parents[1]
GOT10K_PYTHON = Path(os.environ.get("VIDTRACK_GOT10K", REPO / ".venv-got10k" / "bin" / "python"))
DRIVER = Path(__file__).with_name("got10k_reference.py")
TRACKER = "kalman-cv"

pytestmark = [
    pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present"),
    pytest.mark.skipif(not GOT10K_PYTHON.is_file(), reason="no got10k venv (make got10k-env)"),
]


def _evaluate(data, out, shifted=False):
    """Evaluate; ``shifted``: then move every tracked box but the first by 0..45 px and score again.

    The second run reuses the (now shifted) result files, so the scores spread over the
    precision and overlap thresholds rather than a tracker's near-perfect run on a miniature.
    """
    args = ["eval", str(data), "--filter", TRACKER, "--out", str(out), "--in-process", "--no-plots", "-q"]
    assert vidtrack_main(args) == 0
    if shifted:
        for path in (out / TRACKER).glob("*.txt"):
            boxes = np.loadtxt(path, delimiter=",", ndmin=2)
            boxes[1:, 0] += (7 * np.arange(1, len(boxes))) % 46
            np.savetxt(path, boxes, fmt="%.3f", delimiter=",")
        assert vidtrack_main(args) == 0
    return json.loads((out / "summary.json").read_text())[TRACKER]


def _reference(kind, root, results):
    done = subprocess.run([str(GOT10K_PYTHON), str(DRIVER), kind, str(root), str(results), TRACKER],
                          capture_output=True, text=True, timeout=600, check=False,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def _toolkit_name(name: str) -> str:
    """got10k names a two-target folder's sequences Jogging.1, Jogging.2; vidtrack Jogging-1, Jogging-2."""
    base, _, number = name.rpartition("-")
    return f"{base}.{number}" if base in ("Jogging", "Skating2") else name


def _agree_otb_like(ours, theirs):
    assert set(theirs["seq_wise"]) == {_toolkit_name(n) for n in ours if n != "mean"}
    for name, row in ours.items():
        reference = theirs["overall"] if name == "mean" else theirs["seq_wise"][_toolkit_name(name)]
        assert row["auc"] == pytest.approx(reference["success_score"], abs=1e-6), name
        assert row["precision20"] == pytest.approx(reference["precision_score"], abs=1e-6), name
        assert row["pascal"] == pytest.approx(reference["success_rate"], abs=1e-6), name
    return ours["mean"]


SHIFTED = pytest.mark.parametrize("shifted", [False, True], ids=["tracked", "shifted"])


@SHIFTED
def test_otb_agrees_with_the_got10k_toolkit(tmp_path, shifted):
    data = build_otb(tmp_path)
    ours = _evaluate(data, tmp_path / "out", shifted)
    results = tmp_path / "got10k-results" / "OTBtb100" / TRACKER
    results.mkdir(parents=True)
    for path in (tmp_path / "out" / "toolkit" / "otb" / TRACKER).iterdir():
        shutil.copyfile(path, results / f"{_toolkit_name(path.stem)}.txt")
    mean = _agree_otb_like(ours, _reference("otb", data, tmp_path / "got10k-results"))
    if shifted:
        assert 0 < mean["precision20"] < 1 and 0 < mean["pascal"] < 1


@SHIFTED
def test_uav123_agrees_with_the_got10k_toolkit(tmp_path, shifted):
    root = build_uav123(tmp_path) / "UAV123"
    ours = _evaluate(root, tmp_path / "out", shifted)
    shutil.copytree(tmp_path / "out" / "toolkit" / "uav123" / TRACKER, tmp_path / "got10k-results" / "UAV123" / TRACKER)
    mean = _agree_otb_like(ours, _reference("uav123", root, tmp_path / "got10k-results"))
    if shifted:
        assert 0 < mean["precision20"] < 1 and 0 < mean["pascal"] < 1


@SHIFTED
def test_got10k_val_agrees_with_the_got10k_toolkit(tmp_path, shifted):
    data = build_got10k(tmp_path)
    ours = _evaluate(data, tmp_path / "out", shifted)
    shutil.copytree(tmp_path / "out" / "toolkit" / "got10k" / TRACKER,
                    tmp_path / "got10k-results" / "GOT-10k" / TRACKER)
    theirs = _reference("got10k", data.parent, tmp_path / "got10k-results")
    pooled = []
    for name, row in ours.items():
        reference = theirs["overall"] if name == "mean" else theirs["seq_wise"][name]
        assert row["ao"] == pytest.approx(reference["ao"], abs=1e-6), name
        assert row["sr50"] == pytest.approx(reference["sr"], abs=1e-6), name
        if name != "mean":  # the toolkit reads each frame's time from <seq>_time.txt: its speed is mean(1 / t)
            times = np.array(json.loads((tmp_path / "out" / TRACKER / f"{name}.json").read_text())["frame_seconds"])
            pooled.append(times)
            assert reference["speed_fps"] == pytest.approx(np.mean(1 / times), rel=1e-3), name
    assert theirs["overall"]["speed_fps"] == pytest.approx(np.mean(1 / np.concatenate(pooled)), rel=1e-3)
    if shifted:
        assert 0 < ours["mean"]["sr50"] < 1
