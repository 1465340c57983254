"""Whether an evaluation run loses its success AUC through the box's centre or through its size.

For each sequence of a ``vidtrack eval`` output folder this prints the
tracker's success AUC as ``vidtrack eval`` scores it, the AUC of the same run
with the ground truth's size at each of its centres (what a perfect size
would score) and with its size at each true centre (what a perfect centre
would score), from :func:`vidtrack.eval.scoring.centre_and_size_aucs`.  The
gap between the first and the second is what the size costs, between the
first and the third what the centre costs::

    vidtrack eval ../shared/data/sequences --sequences David,Human9 --filter mil --out RUN
    python scripts/centre_or_size.py RUN ../shared/data/sequences
    python scripts/centre_or_size.py RUN ../shared/data/sequences --filter mil

A sequence whose ground truth has one box size in every annotated frame
(the original MIL sequences, :func:`vidtrack.eval.metrics.fixed_size`) is
marked: there any size change the tracker makes is scored as an error, also
one the target made.  The frames are those ``vidtrack eval`` scores: the
annotated ground-truth rows the run tracked.  A path that is not a folder, a
run without result files or a sequence the dataset does not have stops the
script with one line on stderr.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.errors import VidtrackError  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.eval.metrics import fixed_size  # noqa: E402
from vidtrack.eval.results import RESULT_SUFFIX, read_record, result_paths, run_sequences  # noqa: E402
from vidtrack.eval.scoring import centre_and_size_aucs, read_result, tracked_rows  # noqa: E402


def sequence_aucs(sequence, run: Path, name: str) -> tuple[float, float, float]:
    """``(auc, auc with true sizes, auc with true centres)`` of tracker ``name``'s result on ``sequence`` in ``run``."""
    results = read_result(sequence, result_paths(run, name, sequence.name)[0])
    _, mask = tracked_rows(sequence, read_record(run, name, sequence.name))
    return centre_and_size_aucs(sequence, results, mask)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a vidtrack eval output folder (--out)")
    parser.add_argument("dataset", help="the benchmark folder the run was made on")
    parser.add_argument("--filter", help="comma-separated trackers (default: every one in the run)")
    args = parser.parse_args(argv)
    try:
        found = run_sequences(args.run, RESULT_SUFFIX, "result files", args.filter.split(",") if args.filter else None)
        for name, names in found.items():
            print(f"## `{name}`\n")
            print("| sequence | AUC | with true sizes | with true centres | ground-truth size |")
            print("|---|---:|---:|---:|---|")
            table = []
            for sequence in load_dataset(args.dataset, names):
                aucs = sequence_aucs(sequence, args.run, name)
                table.append(aucs)
                size = "one for all frames" if fixed_size(sequence.ground_truth) else "varies"
                print(f"| {sequence.name} | " + " | ".join(f"{v:.3f}" for v in aucs) + f" | {size} |")
            print("| **mean** | " + " | ".join(f"{v:.3f}" for v in np.mean(table, axis=0)) + " | |\n")
    except VidtrackError as exc:
        raise SystemExit(f"centre_or_size: {exc}") from None
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
