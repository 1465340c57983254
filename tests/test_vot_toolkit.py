"""The VOT toolkit (its own venv, `make vot-env`) scores `vidtrack trax` like `vidtrack eval` does.

A workspace in a temporary folder holds a local stack (no ``dataset:`` key,
so nothing is downloaded) with the toolkit's *unsupervised* experiment, one
shared sequence in the VOT layout (its ground truth in 0-based pixels, the
frames read from the shared folder) and a ``trackers.ini`` whose commands
are absolute (the toolkit runs trackers from a temporary folder).
``vot evaluate`` exits 0 even when a tracker failed, so the result files
are checked before ``vot analysis`` is read.
"""

import json
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

from vidtrack.cli import main
from vidtrack.eval.datasets import load_sequence, read_boxes
from vidtrack.eval.metrics import iou
from vidtrack.types import Box

from conftest import SEQUENCES, needs_sequences

VOT = os.environ.get("VIDTRACK_VOT")
SEQUENCE = "Football1"
FILTERS = ("kalman-cv", "mil")
#: The toolkit's overlap rasterises both boxes to pixel masks; vidtrack's IoU is continuous.
RASTER_TOLERANCE = 0.005

STACK = """\
title: vidtrack local check (unsupervised, offline)
experiments:
  baseline:
    type: unsupervised
    analyses:
      - type: average_accuracy
        name: accuracy
        burnin: 1
"""


def test_vidtrack_environment_has_one_opencv_wheel():
    installed = {dist.metadata["Name"].lower() for dist in metadata.distributions()}
    assert "opencv-contrib-python-headless" in installed
    assert not installed & {"opencv-python", "opencv-contrib-python", "opencv-python-headless"}
    assert "vot-toolkit" not in installed


def vot_sequence(folder: Path, sequence) -> None:
    """``folder`` as a VOT sequence: metadata pointing at the shared frames, ground truth in 0-based pixels."""
    folder.mkdir(parents=True)
    pattern = sequence.files[0].parent / f"%0{len(sequence.files[0].stem)}d{sequence.files[0].suffix}"
    assert [p.name for p in sequence.files] == [Path(str(pattern) % (i + 1)).name for i in range(len(sequence))]
    (folder / "sequence").write_text(f"channels.color={pattern}\n")
    boxes = [sequence.to_pixels(sequence.ground_truth_box(row)) for row in range(len(sequence))]
    (folder / "groundtruth.txt").write_text("".join(f"{b.x:g},{b.y:g},{b.w:g},{b.h:g}\n" for b in boxes))


def workspace(root: Path, sequence) -> Path:
    root.mkdir()
    (root / "stack.yaml").write_text(STACK)
    (root / "config.yaml").write_text("stack: stack.yaml\nregistry:\n  - trackers.ini\n")
    (root / "sequences").mkdir()
    (root / "sequences" / "list.txt").write_text(f"{sequence.name}\n")
    vot_sequence(root / "sequences" / sequence.name, sequence)
    (root / "trackers.ini").write_text("".join(
        f"[vidtrack-{name}]\nlabel = vidtrack-{name}\nprotocol = trax\n"
        f"command = {sys.executable} -m vidtrack trax --filter {name}\n\n" for name in FILTERS))
    return root


READ_TRAJECTORIES = """
import json, sys
from vot.region import Special
from vot.region.io import read_trajectory
print(json.dumps([[None if isinstance(r, Special) else [r.x, r.y, r.width, r.height] for r in read_trajectory(path)]
                  for path in sys.argv[1:]]))
"""


def toolkit_boxes(paths: list[Path]) -> list[list]:
    """The toolkit's own reading of result trajectories (its venv's Python, one process): None for special rows."""
    python = Path(VOT).parent / "python"
    result = subprocess.run([str(python), "-c", READ_TRAJECTORIES, *map(str, paths)], capture_output=True,
                            text=True, timeout=120, check=True)
    return json.loads(result.stdout)


def vot(*args, cwd):
    return subprocess.run([VOT, *args], cwd=cwd, capture_output=True, text=True, timeout=600,
                          stdin=subprocess.DEVNULL)


@pytest.mark.slow
@needs_sequences()
@pytest.mark.skipif(not VOT or not Path(VOT).is_file(), reason="VOT toolkit venv not given (make test sets "
                                                                 "VIDTRACK_VOT from `make vot-env`)")
def test_vot_toolkit_accuracy_equals_vidtrack_mean_iou(tmp_path):
    sequence = load_sequence(SEQUENCES / SEQUENCE)
    root = workspace(tmp_path / "workspace", sequence)
    trackers = [f"vidtrack-{name}" for name in FILTERS]

    evaluating = subprocess.Popen([VOT, "evaluate", "--workspace", str(root), *trackers], cwd=tmp_path,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
    try:   # vidtrack eval of the same sequence meanwhile, in this process
        assert main(["eval", str(SEQUENCES), "--filter", ",".join(FILTERS), "--sequences", SEQUENCE,
                     "--out", str(tmp_path / "eval"), "--no-plots", "-q"]) == 0
        output = "".join(evaluating.communicate(timeout=600))
    finally:
        if evaluating.poll() is None:
            evaluating.kill()
            evaluating.communicate()
    assert evaluating.returncode == 0, output
    runs = [root / "results" / tracker / "baseline" / SEQUENCE for tracker in trackers]
    for run in runs:   # the toolkit exits 0 after a tracker failed too: look at what it wrote
        assert (run / f"{SEQUENCE}_001.bin").is_file(), output
        confidence = (run / f"{SEQUENCE}_001_confidence.value").read_text().split()
        assert len(confidence) == len(sequence) and float(confidence[0]) == 1.0
        assert all(0.0 <= float(c) <= 1.0 for c in confidence)
    served = dict(zip(FILTERS, toolkit_boxes([run / f"{SEQUENCE}_001.bin" for run in runs])))
    for boxes in served.values():
        assert len(boxes) == len(sequence) and boxes[0] is None and None not in boxes[1:]   # frame 0: "initialised"

    analysed = vot("analysis", "--workspace", str(root), "--format", "json", "--name", "check", *trackers,
                   cwd=tmp_path)
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    report = json.loads((root / "analysis" / "check.json").read_text())
    assert list(report["trackers"]) == trackers
    toolkit = {name: row[0] for name, row in zip(FILTERS, report["results"]["baseline"]["results"][0])}

    truth = np.array([sequence.to_pixels(sequence.ground_truth_box(row)).as_array() for row in range(len(sequence))])
    rows = []
    for name in FILTERS:
        boxes = np.array([sequence.to_pixels(Box(*row)).as_array()
                          for row in read_boxes(tmp_path / "eval" / name / f"{SEQUENCE}.txt")])
        # the same boxes went through TraX (float32) as eval wrote (3 decimals) ...
        np.testing.assert_allclose(np.array(served[name][1:]), boxes[1:], atol=2e-3)
        # ... so the scores differ only by the toolkit's rasterised overlap (burn-in 1 skips the init frame)
        ours = float(iou(boxes, truth)[1:].mean())
        rows.append(f"| {name:<9} | {SEQUENCE} | {toolkit[name]:>19.4f} | {ours:>17.4f} |")
        assert abs(toolkit[name] - ours) < RASTER_TOLERANCE, (name, toolkit[name], ours)
    print("\n| filter    | sequence  | VOT average overlap | vidtrack mean IoU |\n"
          "|-----------|-----------|--------------------:|------------------:|\n" + "\n".join(rows))
