"""A generated clip of look-alike objects whose paths cross, with its MOT ground truth.

Every object is a rectangle of the same colours (a textured red patch, each
with its own stripe pattern) moving at constant velocity over a textured
background; objects with a higher ID pass in front.  Object 1 moves right,
object 2 moves left along almost the same row (they pass through each other
halfway), object 3 drops through object 1's row a quarter of the way in, object 4
(``--objects 4``) climbs through object 2's path near the end.  Sizes and paths are fractions of the
frame, so ``--size 640x480`` is the same clip at twice the resolution.

Run as a script it writes ``OUT/clip.mp4``, ``OUT/gt.txt`` (MOT Challenge
lines ``frame,id,x,y,w,h,1,-1,-1,-1``, frames 1-based, every object in every
frame) and ``OUT/boxes.txt`` (``id,x,y,w,h`` in the first frame: the input of
``vidtrack --init-boxes``)::

    python tests/crossing_clip.py --seed 0 --out /tmp/crossing
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

#: (start, end) centres as fractions of the frame, per object ID.
PATHS = {
    1: ((0.12, 0.42), (0.82, 0.46)),
    2: ((0.86, 0.50), (0.14, 0.47)),
    3: ((0.295, 0.29), (0.295, 0.89)),
    4: ((0.245, 0.855), (0.345, 0.355)),
}
#: Object size as fractions of the frame (width, height).
SIZE = (0.10, 0.18)


def object_boxes(seed: int, *, size: tuple[int, int] = (320, 240), frames: int = 90,
                 objects: int = 3) -> dict[int, np.ndarray]:
    """Every object's ``(frames, 4)`` boxes ``x, y, w, h`` (0-based pixels); the seed jitters the paths."""
    rng = np.random.default_rng(seed)
    width, height = size
    w, h = SIZE[0] * width, SIZE[1] * height
    t = np.linspace(0.0, 1.0, frames)[:, None]
    boxes = {}
    for target in range(1, objects + 1):
        start, end = (np.array(p) + rng.uniform(-0.02, 0.02, 2) for p in PATHS[target])
        centres = (start + t * (end - start)) * [width, height]
        boxes[target] = np.column_stack([centres[:, 0] - w / 2, centres[:, 1] - h / 2,
                                         np.full(frames, w), np.full(frames, h)])
    return boxes


def _textures(seed: int, size: tuple[int, int], objects: int) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    rng = np.random.default_rng(seed + 1000)
    width, height = size
    noise = rng.normal(0.0, 1.0, (height // 8 + 1, width // 8 + 1, 3))
    background = cv2.resize(noise, (width, height), interpolation=cv2.INTER_CUBIC)
    background = np.clip(110 + 18 * background + [10, 20, 0], 0, 255).astype(np.uint8)
    w, h = int(round(SIZE[0] * width)), int(round(SIZE[1] * height))
    yy, xx = np.mgrid[0:h, 0:w]
    patches = {}
    for target in range(1, objects + 1):
        angle = rng.uniform(0, np.pi)
        period = rng.uniform(0.25, 0.45) * w
        stripes = 0.5 + 0.5 * np.sin((xx * np.cos(angle) + yy * np.sin(angle)) * 2 * np.pi / period)
        base = np.array([40.0, 50.0, 190.0])      # the same red for every object (BGR)
        dark = np.array([30.0, 30.0, 90.0])
        patch = dark + stripes[..., None] * (base - dark) + rng.normal(0, 8, (h, w, 3))
        patches[target] = np.clip(patch, 0, 255).astype(np.uint8)
    return background, patches


def render(seed: int, *, size: tuple[int, int] = (320, 240), frames: int = 90, objects: int = 3):
    """Yield ``(H, W, 3) uint8`` BGR frames of the clip whose boxes :func:`object_boxes` gives."""
    boxes = object_boxes(seed, size=size, frames=frames, objects=objects)
    background, patches = _textures(seed, size, objects)
    width, height = size
    for index in range(frames):
        image = background.copy()
        for target in sorted(boxes):   # higher IDs in front
            patch = patches[target]
            x, y = (int(round(v)) for v in boxes[target][index, :2])
            ph, pw = patch.shape[:2]
            x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + pw, width), min(y + ph, height)
            if x1 > x0 and y1 > y0:
                image[y0:y1, x0:x1] = patch[y0 - y:y1 - y, x0 - x:x1 - x]
        yield image


def write_clip(out: str | Path, seed: int, *, size: tuple[int, int] = (320, 240), frames: int = 90,
               objects: int = 3) -> dict[str, Path]:
    """Write ``clip.mp4``, ``gt.txt`` and ``boxes.txt`` into ``out``; return their paths by name."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"clip": out / "clip.mp4", "gt": out / "gt.txt", "boxes": out / "boxes.txt"}
    writer = cv2.VideoWriter(str(paths["clip"]), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, size)
    for image in render(seed, size=size, frames=frames, objects=objects):
        writer.write(image)
    writer.release()
    boxes = object_boxes(seed, size=size, frames=frames, objects=objects)
    lines = [f"{i + 1},{target},{x:.2f},{y:.2f},{w:.2f},{h:.2f},1,-1,-1,-1"
             for i in range(frames) for target, (x, y, w, h) in
             ((target, boxes[target][i]) for target in sorted(boxes))]
    paths["gt"].write_text("\n".join(lines) + "\n")
    paths["boxes"].write_text("".join(f"{target},{','.join(f'{v:.2f}' for v in boxes[target][0])}\n"
                                      for target in sorted(boxes)))
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--size", default="320x240", help="WxH (default 320x240)")
    parser.add_argument("--frames", type=int, default=90)
    parser.add_argument("--objects", type=int, default=3, choices=(1, 2, 3, 4))
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    for name, path in write_clip(args.out, args.seed, size=(width, height), frames=args.frames,
                                 objects=args.objects).items():
        print(f"{name}: {path}")


if __name__ == "__main__":
    main()
