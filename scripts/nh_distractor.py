"""NormalHedge's robustness claim on video: a look-alike distractor crosses the target.

Chaudhuri, Freund & Hsu ("An Online Learning-based Framework for Tracking")
claim that NormalHedge's clipped loss keeps it on the target where score-map
outliers pull the Bayes filter and the particle filter away.  This script
renders a clip where that outlier is a second copy of the target (a slightly
tinted look-alike) that crosses the target's path in front of it, tracks it
with ``nh``, ``pf`` and ``bayes`` (all on the same correlation-filter score
map) at several seeds, and prints per tracker: the success AUC against the
target, the fraction of the frames after the crossing where the box is on the
distractor rather than the target (IoU with the distractor larger), and the
fraction where it is on neither::

    python scripts/nh_distractor.py --seeds 0,1,2

Each seed renders a different clip (textures, crossing height) and seeds the trackers.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.eval import metrics  # noqa: E402
from vidtrack.recipes import build_tracker  # noqa: E402
from vidtrack.types import Box, Frame  # noqa: E402

SIZE = (320, 240)
BOX = (34, 40)
#: Vertical offset of the look-alike from the target where they cross, in box heights (it hides 40 %).
OFFSET = 0.6


def _texture(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    coarse = rng.random((h // 5 + 2, w // 5 + 2, 3)).astype(np.float32)
    return np.clip(255 * cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def distractor_clip(seed: int, frames: int = 120):
    """Frames, target boxes and distractor boxes of one clip.

    The target walks left to right at mid height; the look-alike (the same
    texture, tinted by a few grey levels) walks right to left on a path that
    crosses the target's near the middle of the clip, ``OFFSET`` box heights
    below it, and is drawn in front of it (a partial occlusion by a look-alike).
    """
    rng = np.random.default_rng(seed)
    W, H = SIZE
    coarse = rng.random((H // 24 + 2, W // 24 + 2, 3)).astype(np.float32)
    background = np.clip(50 + 140 * cv2.resize(coarse, SIZE, interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)
    target = _texture(rng, BOX[1], BOX[0])
    lookalike = np.clip(target.astype(int) + rng.integers(-12, 13, 3), 0, 255).astype(np.uint8)
    y_cross = H / 2 + rng.uniform(-10, 10)
    out, truth, other = [], [], []
    for k in range(frames):
        t = k / (frames - 1)
        tc = np.array([40 + t * (W - 80), y_cross])
        dc = np.array([W - 40 - t * (W - 80), y_cross + OFFSET * BOX[1] + 60 * (0.5 - t)])
        img = background.copy()
        for patch, c in ((target, tc), (lookalike, dc)):   # the distractor is drawn last: in front
            x0, y0 = int(round(c[0] - BOX[0] / 2)), int(round(c[1] - BOX[1] / 2))
            img[y0:y0 + BOX[1], x0:x0 + BOX[0]] = patch
        out.append(Frame(k, img))
        truth.append(Box.from_center(*tc, *BOX))
        other.append(Box.from_center(*dc, *BOX))
    return out, truth, other


def run(filter_name: str, seed: int) -> dict[str, float]:
    frames, truth, other = distractor_clip(seed)
    tracker = build_tracker(filter_name, seed=seed)
    tracker.initialize(frames[0], truth[0])
    boxes = [truth[0]] + [tracker.step(f).box for f in frames[1:]]
    b = np.array([x.as_array() for x in boxes])
    iou_t = metrics.iou(b, np.array([x.as_array() for x in truth]))
    iou_d = metrics.iou(b, np.array([x.as_array() for x in other]))
    after = slice(len(frames) * 2 // 3, None)   # well after the crossing
    return {"auc": metrics.success_auc(iou_t),
            "on_distractor": float(np.mean(iou_d[after] > iou_t[after])),
            "on_neither": float(np.mean((iou_t[after] == 0) & (iou_d[after] == 0)))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--filters", default="nh,pf,bayes")
    parser.add_argument("--seeds", default="0,1,2")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    print("| filter | " + " | ".join(f"seed {s}: AUC / on distractor / on neither" for s in seeds) + " | mean AUC |")
    print("|---|" + "---|" * (len(seeds) + 1))
    for name in args.filters.split(","):
        rows = [run(name, s) for s in seeds]
        cells = [f"{r['auc']:.3f} / {r['on_distractor']:.2f} / {r['on_neither']:.2f}" for r in rows]
        print(f"| {name} | " + " | ".join(cells) + f" | {np.mean([r['auc'] for r in rows]):.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
