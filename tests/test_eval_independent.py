"""An independent scorer, written without vidtrack's metrics or loaders, agrees with the report.

It reads only the ground-truth files, the images' names (to find the MIL frames
range) and the result files, and recomputes the OTB success AUC with plain
Python.  Run it on any evaluation output too::

    python tests/test_eval_independent.py OUT_DIR DATASET_DIR
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from vidtrack.cli import main as vidtrack_main
from vidtrack.eval.synthetic import write_sequence

SEQUENCES = Path(__file__).resolve().parents[2] / "shared/data/sequences"


def _rows(path: Path) -> list[list[float]]:
    return [[float(v) for v in re.split(r"[,\s]+", line.strip()) if v]
            for line in path.read_text().splitlines() if line.strip()]


def _overlap(a, b) -> float:
    ax2, ay2, bx2, by2 = a[0] + a[2], a[1] + a[3], b[0] + b[2], b[1] + b[3]
    iw = max(0.0, min(ax2, bx2) - max(a[0], b[0]))
    ih = max(0.0, min(ay2, by2) - max(a[1], b[1]))
    inter = iw * ih
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def independent_auc(sequence_dir: Path, result_file: Path) -> float:
    """Success AUC over frames with an annotated ground-truth row and a tracked (non-zero) result row."""
    gt_file = sequence_dir / "groundtruth_rect.txt"
    if not gt_file.exists():
        gt_file = next(sequence_dir.glob("*_gt.txt"))
    truth, results = _rows(gt_file), _rows(result_file)
    assert len(truth) == len(results)
    overlaps = [_overlap(r, g) for g, r in zip(truth, results)
                if g[2] > 0 and g[3] > 0 and any(v != 0 for v in r)]
    thresholds = [i / 20 for i in range(21)]
    return sum(sum(o > t for o in overlaps) / len(overlaps) for t in thresholds) / len(thresholds)


def check_directory(out: Path, dataset: Path) -> list[tuple[str, str, float, float]]:
    """``(filter, sequence, reported AUC, independent AUC)`` for every result in ``out``."""
    summary = json.loads((out / "summary.json").read_text())
    checked = []
    for name, rows in summary.items():
        for sequence, row in rows.items():
            if sequence == "mean" or row.get("auc") is None:
                continue
            folder = dataset if dataset.name == sequence else dataset / sequence
            checked.append((name, sequence, row["auc"], independent_auc(folder, out / name / f"{sequence}.txt")))
    return checked


def test_independent_scorer_agrees_on_synthetic_mil_and_otb(tmp_path):
    data = tmp_path / "data"
    write_sequence(data / "Otb", layout="otb", frames=25, separator=" ")
    write_sequence(data / "Mil", layout="mil", frames=30, first_number=0, annotate_every=5,
                   frames_range=(4, 29), velocity=(2.0, 1.0))
    out = tmp_path / "r"
    assert vidtrack_main(["eval", str(data), "--filter", "kalman-cv,ms", "--out", str(out), "-q",
                          "--no-plots", "--in-process"]) == 0
    checked = check_directory(out, data)
    assert len(checked) == 4
    for name, sequence, reported, independent in checked:
        assert abs(reported - independent) < 0.005, (name, sequence, reported, independent)


@pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
def test_independent_scorer_agrees_on_girl(tmp_path):
    out = tmp_path / "r"
    assert vidtrack_main(["eval", str(SEQUENCES), "--sequences", "Girl", "--filter", "kalman-cv",
                          "--max-frames", "150", "--out", str(out), "-q", "--no-plots"]) == 0
    [(_, _, reported, independent)] = check_directory(out, SEQUENCES)
    assert 0 < reported < 1 and abs(reported - independent) < 0.005
    first = (out / "kalman-cv" / "Girl.txt").read_text().splitlines()[0]
    assert first == (SEQUENCES / "Girl" / "groundtruth_rect.txt").read_text().splitlines()[0]  # 1-based kept


if __name__ == "__main__":
    rows = check_directory(Path(sys.argv[1]), Path(sys.argv[2]))
    worst = max(abs(r - i) for *_, r, i in rows)
    for name, sequence, reported, independent in rows:
        print(f"{name:<12} {sequence:<10} report {reported:.4f}  independent {independent:.4f}  "
              f"diff {abs(reported - independent):.2e}")
    print(f"{len(rows)} results checked, largest AUC difference {worst:.2e}")
    sys.exit(0 if worst < 0.005 else 1)
