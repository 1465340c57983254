#!/usr/bin/env python3
"""Render vidtrack's bundled sample clip and its ground truth.

A textured object moves over a textured background with changing velocity
(accelerating, turning, stopping), passes behind an occluder, and a
similar-looking distractor wanders nearby.  Writes ``sample.mp4`` and
``sample_groundtruth.txt`` (one ``x,y,w,h`` line per frame, 0-based pixels,
the true box also while occluded) into ``--out``.  Deterministic for a seed.

Usage::

    python scripts/make_sample.py --out data
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

WIDTH, HEIGHT = 320, 240
OBJECT_SIZE = (36, 44)  # w, h


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], scale: int) -> np.ndarray:
    """Low-frequency noise in [0, 1]: random values on a coarse grid, upsampled."""
    coarse = rng.random((shape[0] // scale + 2, shape[1] // scale + 2)).astype(np.float32)
    up = cv2.resize(coarse, (shape[1] + 2 * scale, shape[0] + 2 * scale), interpolation=cv2.INTER_CUBIC)
    up = up[scale:scale + shape[0], scale:scale + shape[1]]
    return np.clip((up - up.min()) / max(float(np.ptp(up)), 1e-6), 0, 1)


def background(rng: np.random.Generator) -> np.ndarray:
    """Textured background: smooth colour blobs plus fine grain."""
    img = np.zeros((HEIGHT, WIDTH, 3), np.float32)
    for c, (lo, hi) in enumerate([(60, 140), (80, 150), (50, 120)]):
        img[..., c] = lo + (hi - lo) * smooth_noise(rng, (HEIGHT, WIDTH), 40)
    img += rng.normal(0, 6, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def textured_object(rng: np.random.Generator, palette: np.ndarray) -> np.ndarray:
    """A ``(h, w, 3)`` patch: a checker pattern in ``palette`` colours with grain."""
    w, h = OBJECT_SIZE
    yy, xx = np.mgrid[0:h, 0:w]
    cells = ((xx // 6) + (yy // 6)) % len(palette)
    patch = palette[cells].astype(np.float32)
    patch += rng.normal(0, 8, patch.shape)
    return np.clip(patch, 0, 255).astype(np.uint8)


def object_path(n: int) -> np.ndarray:
    """Top-left positions ``(n, 2)`` with changing velocity: accelerate, turn, stop, go."""
    pos = np.zeros((n, 2))
    p = np.array([30.0, 150.0])
    v = np.array([0.5, 0.0])
    for k in range(n):
        t = k / n
        if t < 0.3:
            a = np.array([0.06, -0.03])     # accelerate right and up
        elif t < 0.45:
            a = np.array([-0.02, 0.05])     # turn downwards
        elif t < 0.6:
            a = -0.15 * v                   # brake to a near stop
        else:
            a = np.array([0.05, -0.02])     # move off again
        v = np.clip(v + a, -4, 4)
        p = p + v
        p[0] = np.clip(p[0], 2, WIDTH - OBJECT_SIZE[0] - 2)
        p[1] = np.clip(p[1], 2, HEIGHT - OBJECT_SIZE[1] - 2)
        pos[k] = p
    return pos


def render(n_frames: int, seed: int) -> tuple[list[np.ndarray], np.ndarray]:
    rng = np.random.default_rng(seed)
    bg = background(rng)
    palette = np.array([[40, 40, 200], [230, 230, 240], [30, 160, 240]], np.uint8)  # red, white, orange (BGR)
    target = textured_object(rng, palette)
    distractor = textured_object(rng, palette[[1, 2, 0]])  # same colours, shifted pattern
    path = object_path(n_frames)
    occluder_x = (150, 204)  # a vertical post the target passes behind
    occluder = np.clip(np.full((HEIGHT, occluder_x[1] - occluder_x[0], 3), (90, 90, 95), np.float32)
                       + rng.normal(0, 10, (HEIGHT, occluder_x[1] - occluder_x[0], 3)), 0, 255).astype(np.uint8)
    w, h = OBJECT_SIZE
    frames, boxes = [], []
    for k in range(n_frames):
        img = bg.copy()
        # The distractor circles in the upper right.
        dx = int(235 + 45 * np.cos(2 * np.pi * k / 90.0))
        dy = int(40 + 25 * np.sin(2 * np.pi * k / 90.0))
        img[dy:dy + h, dx:dx + w] = distractor
        x, y = path[k]
        xi, yi = int(round(x)), int(round(y))
        img[yi:yi + h, xi:xi + w] = target
        img[:, occluder_x[0]:occluder_x[1]] = occluder
        noise = rng.normal(0, 3, img.shape)
        frames.append(np.clip(img + noise, 0, 255).astype(np.uint8))
        boxes.append((xi, yi, w, h))
    return frames, np.array(boxes, float)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="data", help="output folder (default data)")
    parser.add_argument("--frames", type=int, default=150, help="number of frames (default 150)")
    parser.add_argument("--seed", type=int, default=7, help="random seed (default 7)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    frames, boxes = render(args.frames, args.seed)
    writer = cv2.VideoWriter(str(out / "sample.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (WIDTH, HEIGHT))
    for frame in frames:
        writer.write(frame)
    writer.release()
    np.savetxt(out / "sample_groundtruth.txt", boxes, fmt="%d", delimiter=",")
    print(f"wrote {out / 'sample.mp4'} ({len(frames)} frames) and {out / 'sample_groundtruth.txt'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
