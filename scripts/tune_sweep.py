"""Sweep a tracker's settings on the *tune* split at several seeds (how defaults are chosen).

Each configuration is a set of settings with the keys ``vidtrack --set``
takes (dotted for a group: ``fusion.motion``), given as ``KEY=VALUE`` pairs
separated by spaces, or as a TOML file (``--config`` takes both, once per
configuration; none: the tracker's defaults).  Every (configuration, seed,
sequence) runs in a process pool and the table prints the mean success AUC
over the sequences at each random seed, its mean over all seeds, the worst
seed, and the sequences whose AUC spreads most from seed to seed (a default
must not depend on a lucky seed)::

    python scripts/tune_sweep.py ../shared/data/sequences --filter mil \\
        --config '' --config 'superpixels.slic=opencv' \\
        --config 'fusion.motion=0.1 fusion.min_quality=0.2' --seeds 0,1,2 --jobs 2

``--group NAME=A,B,...`` (once per group; the sequences among those swept)
adds a table of each configuration's mean AUC per seed, and over the seeds,
over just those sequences: whether a change helps the whole split or only a
kind of sequence in it.

Several dataset folders sweep the same sequences in each: *tune* and the
copies of it that ``scripts/occlude_sequences.py``, ``stride_sequences.py``,
``zoom_sequences.py`` and ``edge_sequences.py`` write, so a setting is judged
on all of them in one run (``docs/evaluation.md``, "What *tune* rewards").
Each folder gets its tables, headed by its path, and a last table gives each
configuration's mean over the seeds in every folder and over the folders::

    python scripts/tune_sweep.py ../shared/data/sequences OCCLUDED ZOOMED --filter mil \
        --config '' --config 'kalman.r_size=0.1'

A key the tracker does not take, a value of the wrong type, a malformed
``--seeds`` or ``--group``, or a folder without one of the sequences stops the
sweep before it starts, with one line on stderr and exit status 2.  It
refuses sequences of the *validate* split: those are reported, never tuned on
(``../shared/data/sequences/INDEX.md``).
Per-sequence AUCs go to ``--json``: one entry per folder and configuration,
``{"dataset", "settings", "auc": {sequence: {seed: AUC}}}``, the folders in
the order given.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import NoReturn

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.config import parse_setting, read_toml  # noqa: E402
from vidtrack.errors import DatasetError, UsageError  # noqa: E402
from vidtrack.eval import metrics  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.recipes import build_tracker, recipe_config  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402

TUNE = "David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling"
VALIDATE = {"Couple", "Crossing", "Dog", "Freeman1", "Human8", "Jogging", "Suv"}


def parse_config(text: str) -> dict[str, object]:
    """The settings of one ``--config``: a TOML file's, or space-separated ``KEY=VALUE`` pairs (empty: none)."""
    if text.strip().endswith(".toml"):
        return read_toml(text.strip())
    return dict(parse_setting(item) for item in text.split())


def run_one(dataset: str, name: str, filter_name: str, settings: dict, seed: int) -> float:
    """Success AUC of ``filter_name`` with ``settings`` on sequence ``name`` at ``seed``."""
    (seq,) = load_dataset(dataset, [name])
    start, stop = seq.eval_range
    source = ImageFolderSource(seq.path, files=list(seq.files[start:stop]))
    init = seq.to_pixels(seq.ground_truth_box(start))
    tracker = build_tracker(filter_name, seed=seed, settings=settings)
    boxes = []
    for count, frame in enumerate(source):
        state = tracker.initialize(frame, init) if count == 0 else tracker.step(frame)
        boxes.append(seq.from_pixels(state.box).as_array())
    return float(metrics.score(np.array(boxes), seq.ground_truth[start:stop])["auc"])


def parse_group(text: str, names: list[str]) -> tuple[str, list[str]]:
    """``NAME=A,B,...`` as ``(NAME, [A, B, ...])``; the sequences must be among the swept ``names``, once each."""
    name, sep, members = text.partition("=")
    name = name.strip()
    chosen = [m.strip() for m in members.split(",") if m.strip()]
    if not sep or not name or not chosen:
        raise ValueError(f"--group {text!r}: expected NAME=SEQUENCE,SEQUENCE,...")
    unknown = [m for m in chosen if m not in names]
    if unknown:
        raise ValueError(f"--group {name}: {', '.join(unknown)} not among the swept sequences")
    if len(set(chosen)) < len(chosen):
        raise ValueError(f"--group {name}: a sequence is named twice")
    return name, chosen


def label(settings: dict) -> str:
    """A configuration as the table shows it: its settings, ``KEY=VALUE`` separated by spaces."""
    return " ".join(f"{key}={value}" for key, value in settings.items()) or "(defaults)"


def print_tables(results: dict, configs: list[dict], seeds: list[int], names: list[str],
                 groups: list[tuple[str, list[str]]]) -> None:
    """One folder's tables: every configuration's mean AUC per seed, then each group's."""
    print("| config | " + " | ".join(f"seed {s}" for s in seeds) + " | mean | worst seed | widest spreads |")
    print("|---|" + "---|" * (len(seeds) + 3))
    for i, c in enumerate(configs):
        per_seed = [np.mean([results[i, s, n] for n in names]) for s in seeds]
        spread = {n: max(results[i, s, n] for s in seeds) - min(results[i, s, n] for s in seeds) for n in names}
        widest = sorted(spread, key=spread.get, reverse=True)[:3]
        print(f"| `{label(c)}` | " + " | ".join(f"{v:.3f}" for v in per_seed)
              + f" | **{np.mean(per_seed):.3f}** | {min(per_seed):.3f} | "
              + ", ".join(f"{n} {spread[n]:.2f}" for n in widest) + " |", flush=True)
    for group, members in groups:
        print(f"\n{group} ({', '.join(members)}): mean AUC per seed\n")
        print("| config | " + " | ".join(f"seed {s}" for s in seeds) + " | mean |")
        print("|---|" + "---|" * (len(seeds) + 1))
        for i, c in enumerate(configs):
            per_seed = [np.mean([results[i, s, n] for n in members]) for s in seeds]
            print(f"| `{label(c)}` | " + " | ".join(f"{v:.3f}" for v in per_seed) + f" | **{np.mean(per_seed):.3f}** |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", nargs="+", metavar="dataset",
                        help="a folder of the sequences (several: the same sequences swept in each)")
    parser.add_argument("--filter", default="mil")
    parser.add_argument("--config", action="append", default=[],
                        help="one configuration: 'KEY=VALUE KEY=VALUE ...' or FILE.toml (repeat for several)")
    parser.add_argument("--sequences", default=TUNE)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", help="write every per-sequence AUC here")
    parser.add_argument("--group", action="append", default=[], metavar="NAME=A,B,...",
                        help="also print the mean AUC over these sequences alone (repeat for several groups)")
    args = parser.parse_args(argv)

    def stop(message: str) -> NoReturn:
        parser.exit(2, f"tune_sweep.py: {message}\n")

    names = args.sequences.split(",")
    if VALIDATE & set(names):
        stop(f"{', '.join(sorted(VALIDATE & set(names)))} belong to the validate split: never tune on them")
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        stop(f"--seeds {args.seeds!r}: expected integers separated by commas")
    try:
        groups = [parse_group(g, names) for g in args.group]
    except ValueError as exc:
        stop(str(exc))
    if len({name for name, _ in groups}) < len(groups):
        stop("two --group share a name")
    try:
        configs = [parse_config(c) for c in (args.config or [""])]
        for settings in configs:   # a bad key or value stops the sweep here, not in a worker
            recipe_config(args.filter, settings)
    except UsageError as exc:
        stop(str(exc))
    for dataset in args.datasets:   # every folder holds every sequence, readable
        try:
            load_dataset(dataset, names)
        except DatasetError as exc:
            stop(str(exc))
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = {(d, i, s, n): pool.submit(run_one, dataset, n, args.filter, c, s)
                   for d, dataset in enumerate(args.datasets)
                   for i, c in enumerate(configs) for s in seeds for n in names}
        results = {key: f.result() for key, f in futures.items()}
    several = len(args.datasets) > 1
    table = []
    for d, dataset in enumerate(args.datasets):
        mine = {key[1:]: auc for key, auc in results.items() if key[0] == d}
        if several:
            print(("\n" if d else "") + f"{dataset}:\n")
        print_tables(mine, configs, seeds, names, groups)
        table += [{"dataset": dataset, "settings": c, "auc": {n: {s: mine[i, s, n] for s in seeds} for n in names}}
                  for i, c in enumerate(configs)]
    if several:
        print("\nMean AUC over the seeds, per folder and over the folders\n")
        print("| config | " + " | ".join(args.datasets) + " | all |")
        print("|---|" + "---|" * (len(args.datasets) + 1))
        for i, c in enumerate(configs):
            per_folder = [np.mean([results[d, i, s, n] for s in seeds for n in names])
                          for d in range(len(args.datasets))]
            print(f"| `{label(c)}` | " + " | ".join(f"{v:.3f}" for v in per_folder)
                  + f" | **{np.mean(per_folder):.3f}** |")
    if args.json:
        Path(args.json).write_text(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
