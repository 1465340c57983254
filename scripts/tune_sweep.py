"""Sweep a tracker's options on the *tune* split at several seeds: the protocol defaults are chosen by.

Each configuration is a JSON object of options for :func:`vidtrack.track`;
every (configuration, seed, sequence) runs in a process pool and the table
prints the mean success AUC over the sequences at each seed, the mean over
the seeds, the worst seed, and the sequences whose AUC spreads most over the
seeds (a default must not depend on a lucky seed)::

    python scripts/tune_sweep.py ../shared/data/sequences --filter mil \\
        --config '{}' --config '{"slic": "opencv"}' --seeds 0,1,2 --jobs 2

It refuses sequences of the *validate* split: those are reported, never tuned on
(``../shared/data/sequences/INDEX.md``).  Per-sequence AUCs go to ``--json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import vidtrack  # noqa: E402
from vidtrack.eval import metrics  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402

TUNE = "David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling"
VALIDATE = {"Couple", "Crossing", "Dog", "Freeman1", "Human8", "Jogging", "Suv"}


def run_one(dataset: str, name: str, filter_name: str, options: dict, seed: int) -> float:
    """Success AUC of ``filter_name`` with ``options`` on sequence ``name`` at ``seed``."""
    (seq,) = load_dataset(dataset, [name])
    start, stop = seq.eval_range
    source = ImageFolderSource(seq.path, files=list(seq.files[start:stop]))
    init = seq.to_pixels(seq.ground_truth_box(start))
    boxes = [seq.from_pixels(s.box).as_array()
             for s in vidtrack.track(source, init, filter_name, seed=seed, **options)]
    return float(metrics.score(np.array(boxes), seq.ground_truth[start:stop])["auc"])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--filter", default="mil")
    parser.add_argument("--config", action="append", default=[], help="JSON options (repeat for several)")
    parser.add_argument("--sequences", default=TUNE)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", help="write every per-sequence AUC here")
    args = parser.parse_args(argv)
    names = args.sequences.split(",")
    if VALIDATE & set(names):
        parser.error(f"{sorted(VALIDATE & set(names))} belong to the validate split: never tune on them")
    seeds = [int(s) for s in args.seeds.split(",")]
    configs = [json.loads(c) for c in (args.config or ["{}"])]
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = {(i, s, n): pool.submit(run_one, args.dataset, n, args.filter, c, s)
                   for i, c in enumerate(configs) for s in seeds for n in names}
        results = {key: f.result() for key, f in futures.items()}
    print("| config | " + " | ".join(f"seed {s}" for s in seeds) + " | mean | worst seed | widest spreads |")
    print("|---|" + "---|" * (len(seeds) + 3))
    table = []
    for i, c in enumerate(configs):
        per_seed = [np.mean([results[i, s, n] for n in names]) for s in seeds]
        spread = {n: max(results[i, s, n] for s in seeds) - min(results[i, s, n] for s in seeds) for n in names}
        widest = sorted(spread, key=spread.get, reverse=True)[:3]
        print(f"| `{json.dumps(c)}` | " + " | ".join(f"{v:.3f}" for v in per_seed)
              + f" | **{np.mean(per_seed):.3f}** | {min(per_seed):.3f} | "
              + ", ".join(f"{n} {spread[n]:.2f}" for n in widest) + " |", flush=True)
        table.append({"config": c, "auc": {n: {s: results[i, s, n] for s in seeds} for n in names}})
    if args.json:
        Path(args.json).write_text(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
