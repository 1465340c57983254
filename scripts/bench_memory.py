#!/usr/bin/env python3
"""Peak memory of a tracking run against its length: vidtrack streams, so it should stay flat.

Runs ``vidtrack VIDEO --init-box BOX --filter NAME --max-frames N`` in a fresh
process for each filter and each N and prints the process's peak resident set
size (``ru_maxrss``), with the ratio of the longest run's peak to the shortest's.
Without ``VIDEO`` it generates a long synthetic clip first (a textured square
moving on a circle over a gradient, H.264), so a 10,000-frame stream needs no
download.

Usage::

    python scripts/bench_memory.py --filter mil,nh,cbt,svk,kalman-cv,opencv-kcf --frames 1000,10000
    python scripts/bench_memory.py ../shared/data/sequences/Sylvester/img --init-box 122,51,51,61 \
        --filter kalman-cv --frames 100,1344
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CHILD = """
import resource, sys
from vidtrack.cli import main
code = main(sys.argv[1:])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""

WIDTH, HEIGHT, SIDE = 160, 120, 24


def square_position(index: int) -> tuple[int, int]:
    """Top-left corner of the square in frame ``index`` (one turn every 300 frames)."""
    angle = index * 2 * np.pi / 300
    return (int(round((WIDTH - SIDE) / 2 + 40 * np.cos(angle))),
            int(round((HEIGHT - SIDE) / 2 + 30 * np.sin(angle))))


def make_video(path: Path, frames: int) -> str:
    """Write the synthetic clip; returns its init box ``x,y,w,h``."""
    from vidtrack.sinks.h264 import H264Writer

    background = np.empty((HEIGHT, WIDTH, 3), np.uint8)
    background[:] = np.linspace(40, 140, WIDTH, dtype=np.uint8)[None, :, None]
    patch = (np.indices((SIDE, SIDE)).sum(axis=0) % 6 * 35 + 40).astype(np.uint8)
    patch = np.stack([patch, 255 - patch, np.full_like(patch, 200)], axis=-1)
    writer = H264Writer(path, fps=30.0, batch=60)
    try:
        for index in range(frames):
            image = background.copy()
            x, y = square_position(index)
            image[y:y + SIDE, x:x + SIDE] = patch
            writer.write(image)
    finally:
        writer.close()
    x, y = square_position(0)
    return f"{x},{y},{SIDE},{SIDE}"


def peak_rss_mb(video: str, box: str, name: str, frames: int, tmp: str) -> float:
    result = subprocess.run([sys.executable, "-c", CHILD, video, "--init-box", box, "--filter", name,
                             "--max-frames", str(frames), "--quiet", "--boxes", f"{tmp}/b.txt"],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"{name}: {result.stderr.strip().splitlines()[-1] if result.stderr.strip() else result.returncode}")
    tracked = sum(1 for _ in open(f"{tmp}/b.txt"))
    if tracked != frames:
        raise SystemExit(f"{name}: tracked {tracked} frames, not {frames} (video too short?)")
    return int(result.stdout.split()[-1]) / 1024


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("video", nargs="?", help="video or frame folder (default: a generated clip)")
    parser.add_argument("--init-box", help="needed with VIDEO")
    parser.add_argument("--filter", default="kalman-cv", help="comma-separated filter names")
    parser.add_argument("--frames", default="1000,10000", help="comma-separated run lengths")
    args = parser.parse_args()
    lengths = [int(v) for v in args.frames.split(",")]
    names = [n for n in args.filter.split(",") if n]
    with tempfile.TemporaryDirectory() as tmp:
        video, box = args.video, args.init_box
        if video is None:
            video = f"{tmp}/synthetic.mp4"
            box = make_video(Path(video), max(lengths))
        elif box is None:
            parser.error("--init-box is needed with VIDEO")
        header = " | ".join(f"peak RSS at {n} frames (MB)" for n in lengths)
        print(f"| filter | {header} | ratio last/first |")
        print("|---|" + "---:|" * (len(lengths) + 1))
        for name in names:
            peaks = [peak_rss_mb(video, box, name, n, tmp) for n in lengths]
            cells = " | ".join(f"{p:.1f}" for p in peaks)
            print(f"| {name} | {cells} | {peaks[-1] / peaks[0]:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
