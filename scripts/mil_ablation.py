"""Ablation of ``mil``: the paper's tracker, the default with each extension removed in turn, the default.

Runs each configuration on benchmark sequences (default: the *validate*
split of ``../shared/data/sequences``) at one seed and prints a table of the
success AUC per sequence, the mean AUC and PASCAL score and the tracking fps,
so it is visible what the superpixel / SVM / graph-cut core contributes and
what each extension buys::

    python scripts/mil_ablation.py ../shared/data/sequences --seed 0

Each row is a :class:`~vidtrack.recipes.mil.MILConfig`: a preset (``mil``,
``mil-paper``) or ``mil`` with a few settings changed
(:func:`vidtrack.config.with_settings`, the keys ``--set`` takes); scores use
:mod:`vidtrack.eval.metrics` on the sequences' own frames.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.config import with_settings  # noqa: E402
from vidtrack.eval import metrics  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.recipes import recipe_config  # noqa: E402
from vidtrack.recipes.mil import MILConfig, build_mil  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402

VALIDATE = "Couple,Crossing,Dog,Freeman1,Human8,Jogging,Suv"


MIL = recipe_config("mil")

#: name -> the configuration of the row
CONFIGS = {
    "paper (mil-paper)": recipe_config("mil-paper"),
    "default - cf centre fusion": with_settings(MIL, {"fusion.refine": False}),
    "default - cf scale": with_settings(MIL, {"fusion.size_from": "none"}),
    "default - re-detection": with_settings(MIL, {"fusion.redetect": False}),
    "default - search when reported lost": with_settings(MIL, {"fusion.search_when_lost": False}),
    "default - search again at the filter's peak": with_settings(MIL, {"fusion.recentre": None}),
    "default - lost bag": with_settings(MIL, {"graphcut.lost_bag": False}),
    "default - cf constraint (DSST filter)": with_settings(MIL, {"correlation.constrained": False}),
    "default - cf colour merge": with_settings(MIL, {"correlation.colour_merge": 0.0}),
    "default - cf sample reuse (re-cut window)": with_settings(MIL, {"correlation.reuse_sample": False}),
    "default - cf every-sample objective (average sample, whole box, solved every frame)": with_settings(
        MIL, {"correlation.second_moment": False, "correlation.support": 1.0, "correlation.solve_interval": 1,
              "correlation.admm_iterations": 2}),
    "correlation filter alone (no superpixel core)": with_settings(MIL, {"fusion.core": False}),
    "default, OpenCV's SLIC instead of the compiled one": with_settings(MIL, {"superpixels.slic": "opencv"}),
    "default (mil)": MIL,
}


def score_config(sequences, config: MILConfig, seed: int) -> dict[str, tuple[float, float, float]]:
    """``{sequence: (auc, pascal, fps)}`` of the MIL tracker configured by ``config``."""
    out = {}
    for seq in sequences:
        start, stop = seq.eval_range
        source = ImageFolderSource(seq.path, files=list(seq.files[start:stop]))
        init = seq.to_pixels(seq.ground_truth_box(start))
        tracker = build_mil(config, seed=seed)
        t0 = time.perf_counter()
        boxes = []
        for count, frame in enumerate(source):
            state = tracker.initialize(frame, init) if count == 0 else tracker.step(frame)
            boxes.append(seq.from_pixels(state.box).as_array())
        seconds = time.perf_counter() - t0
        s = metrics.score(np.array(boxes), seq.ground_truth[start:stop])
        out[seq.name] = (s["auc"], s["pascal"], len(boxes) / seconds)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--sequences", default=VALIDATE)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--configs", help="comma-separated subset of the configuration names")
    args = parser.parse_args(argv)
    names = args.configs.split(",") if args.configs else list(CONFIGS)
    unknown = [name for name in names if name not in CONFIGS]
    if unknown:
        parser.error(f"unknown configuration {unknown[0]!r}; valid: {', '.join(CONFIGS)}")
    sequences = load_dataset(args.dataset, args.sequences.split(","))
    short = [s.name for s in sequences]
    print("| configuration | " + " | ".join(short) + " | mean AUC | PASCAL | fps (decoding included) |")
    print("|---|" + "---|" * (len(short) + 3))
    for name in names:
        rows = score_config(sequences, CONFIGS[name], args.seed)
        aucs = [rows[n][0] for n in short]
        print(f"| {name} | " + " | ".join(f"{a:.3f}" for a in aucs)
              + f" | {np.mean(aucs):.3f} | {np.mean([rows[n][1] for n in short]):.3f}"
              + f" | {np.mean([rows[n][2] for n in short]):.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
