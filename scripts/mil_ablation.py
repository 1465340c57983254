"""Ablation of ``mil``: the paper's tracker, the default with each extension removed in turn, the default.

Runs each configuration on benchmark sequences (default: the *validate*
split of ``../shared/data/sequences``) at one seed and prints a table of the
success AUC per sequence, the mean AUC and PASCAL score and the tracking fps,
so it is visible what the superpixel / SVM / graph-cut core contributes and
what each extension buys::

    python scripts/mil_ablation.py ../shared/data/sequences --seed 0

Each configuration is run through :func:`vidtrack.track` with the options
below; scores use :mod:`vidtrack.eval.metrics` on the sequences' own frames.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import vidtrack  # noqa: E402
from vidtrack.eval import metrics  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402

VALIDATE = "Couple,Crossing,Dog,Freeman1,Human8,Jogging,Suv"

#: name -> options of build_tracker("mil", ...)
CONFIGS = {
    "paper (no extension)": dict(refine="none", size_from="inliers", redetect=False, lost_bag=False),
    "default - cf centre fusion": dict(refine="none"),
    "default - cf scale": dict(size_from="none"),
    "default - re-detection": dict(redetect=False),
    "default - lost bag": dict(lost_bag=False),
    "default, ncc refinement instead of cf": dict(refine="ncc"),
    "default - cf constraint (DSST filter)": dict(cf_constrained=False),
    "default - cf colour merge": dict(cf_colour_merge=0.0),
    "default - cf sample reuse (re-cut window)": dict(cf_reuse_sample=False),
    "default - scale filter learning (frozen at frame 1, as before the fix)": dict(cf_options={"scale_update": False}),
    "default, OpenCV's SLIC instead of the compiled one": dict(slic="opencv"),
    "default": dict(),
}


def score_config(sequences, options: dict, seed: int) -> dict[str, tuple[float, float, float]]:
    """``{sequence: (auc, pascal, fps)}`` of mil with ``options``."""
    out = {}
    for seq in sequences:
        start, stop = seq.eval_range
        source = ImageFolderSource(seq.path, files=list(seq.files[start:stop]))
        init = seq.to_pixels(seq.ground_truth_box(start))
        t0 = time.perf_counter()
        boxes = [seq.from_pixels(s.box).as_array() for s in vidtrack.track(source, init, "mil", seed=seed, **options)]
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
    sequences = load_dataset(args.dataset, args.sequences.split(","))
    names = args.configs.split(",") if args.configs else list(CONFIGS)
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
