#!/usr/bin/env python3
"""Peak memory and time per frame of every tracker on large frames, small boxes and long streams.

Each tracker runs in a fresh process through the real run loop
(:func:`vidtrack.run.run_tracker`, with a ``--boxes`` sink) on frames
generated on the fly: a textured target the size of the box moving on an
ellipse (1.5 box sizes wide, one high, one turn every 120 frames) over a
smooth textured background, so no video has to be stored.  Every case's
frame is the centre of one 3840x2160 world: around the target the frames of
all cases hold the same pixels, so a tracker does the same thing on each and
the time per frame differs only by the work that follows the frame.  The cases:

=========  ===========  =========  ===============================================
case       frame        box        what it checks
=========  ===========  =========  ===============================================
``vga``    640x480      40x40      the reference for the time per frame
``4k``     3840x2160    40x40      time per frame within 1.5x of ``vga``'s
``small``  1280x720     10x10      a small box on a large frame (frame/box ratio)
``long``   160x120      24x24      ``--long-frames`` frames (default 100,000):
                                   peak RSS at the end within 10 % of that after
                                   1,000 frames
=========  ===========  =========  ===============================================

and every case's peak resident set size (``ru_maxrss``) under 1 GB.  The
time per frame is the tracker's alone (generating the frame and writing the
boxes excluded), the median over the frames (the machine may be shared: the
median ignores the frames another process slowed down), as wall-clock time
(``ms``) and as the process's CPU time (``cpu ms``, all its threads; time
spent waiting for a core is not in it).  The 1.5x check compares CPU times:
on a busy machine the wall-clock ratio measures the other processes too.  A tracker that refuses a case (a documented memory budget,
exit 2 on the command line) is listed with its one-line reason.

Usage::

    nice -n 10 python scripts/bench_memory.py                         # every tracker, every case
    python scripts/bench_memory.py --filter cbt,nh --cases vga,4k,small --frames 100
    python scripts/bench_memory.py --filter kalman-cv --cases long --long-frames 5000
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

#: name -> (width, height, box side)
CASES = {"vga": (640, 480, 40), "4k": (3840, 2160, 40), "small": (1280, 720, 10), "long": (160, 120, 24)}
CHECKPOINT = 1000
RSS_LIMIT_MB = 1024.0
GROWTH_LIMIT = 1.10
SLOWDOWN_LIMIT = 1.5


#: The generated world every case's frame is cut from, centred: the target's surroundings are the same
#: pixels in every case, so the time per frame of two cases with one box size differs only by the frame.
WORLD = (3840, 2160)
CELL = 24   # pixels per cell of the background's coarse noise


class SyntheticStream:
    """Frames ``(H, W, 3) uint8`` with a textured ``side x side`` target moving on an ellipse.

    The background is the centre ``W x H`` of one 3840x2160 world (smooth
    noise, low-resolution noise resized up, over a horizontal gradient), so
    a 640x480 frame holds the same pixels as the middle of a 3840x2160 one;
    only the part a frame shows is generated.  The target is a fixed finer
    texture in other colours.  ``box(index)`` is the target's true box
    ``(x, y, w, h)``.
    """

    def __init__(self, width: int, height: int, side: int, frames: int, *, seed: int = 0) -> None:
        import cv2

        rng = np.random.default_rng(seed)
        self.width, self.height, self.side, self.frames = width, height, side, frames
        world_w, world_h = WORLD
        if width > world_w or height > world_h:
            raise ValueError(f"frames up to {world_w}x{world_h}")
        coarse = rng.integers(0, 256, (world_h // CELL, world_w // CELL, 3), dtype=np.uint8)
        left, top = (world_w - width) // 2, (world_h - height) // 2
        # the cells under the frame and 3 more a side (the cubic kernel's reach): the same pixels as the
        # whole world resized, cut to the frame
        c0, r0 = max(left // CELL - 3, 0), max(top // CELL - 3, 0)
        c1, r1 = min(-(-(left + width) // CELL) + 3, world_w // CELL), min(-(-(top + height) // CELL) + 3,
                                                                            world_h // CELL)
        cells = coarse[r0:r1, c0:c1]
        smooth = cv2.resize(cells, (cells.shape[1] * CELL, cells.shape[0] * CELL), interpolation=cv2.INTER_CUBIC)
        x0, y0 = left - c0 * CELL, top - r0 * CELL
        smooth = smooth[y0:y0 + height, x0:x0 + width].astype(np.int16)
        ramp = np.linspace(-30, 30, world_w).astype(np.int16)[left:left + width][None, :, None]
        self.background = np.clip(smooth // 2 + 64 + ramp, 0, 255).astype(np.uint8)
        cells = max(2, side // 3)
        pattern = rng.integers(0, 256, (cells, cells, 3), dtype=np.uint8)
        pattern[..., 2] = 255 - pattern[..., 0]
        self.patch = cv2.resize(pattern, (side, side), interpolation=cv2.INTER_NEAREST)

    def box(self, index: int) -> tuple[int, int, int, int]:
        angle = index * 2 * np.pi / 120
        cx = self.width / 2 + 1.5 * self.side * np.cos(angle)
        cy = self.height / 2 + 1.0 * self.side * np.sin(angle)
        return int(round(cx - self.side / 2)), int(round(cy - self.side / 2)), self.side, self.side

    def __iter__(self):
        from vidtrack.types import Frame

        for index in range(self.frames):
            image = self.background.copy()
            x, y, w, h = self.box(index)
            image[y:y + h, x:x + w] = self.patch
            yield Frame(index, image)


def child(name: str, case: str, frames: int, boxes: str) -> dict:
    """Run ``name`` on ``case`` in this process; the peak RSS at the checkpoint and at the end, ms per frame."""
    from vidtrack.errors import VidtrackError
    from vidtrack.recipes import build_tracker
    from vidtrack.run import run_tracker
    from vidtrack.sinks.files import BoxesSink
    from vidtrack.types import Box

    width, height, side = CASES[case]
    stream = SyntheticStream(width, height, side, frames)
    at_checkpoint: list[float] = []

    def on_frame(frame, states) -> None:
        if frame.index + 1 == min(CHECKPOINT, frames):
            at_checkpoint.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)

    times = np.full(frames, np.nan)   # allocated before the run: the bench's own memory stays flat
    cpu = np.full(frames, np.nan)
    try:
        tracker = build_tracker(name, seed=0)
        step = tracker.step

        def timed_step(frame):
            start, start_cpu = time.perf_counter(), time.process_time()
            state = step(frame)
            times[frame.index] = time.perf_counter() - start
            cpu[frame.index] = time.process_time() - start_cpu
            return state

        tracker.step = timed_step
        result = run_tracker(tracker, stream, Box(*map(float, stream.box(0))), [BoxesSink(boxes)],
                             on_frame=on_frame)
    except VidtrackError as exc:
        return {"refused": str(exc)}
    end = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"frames": result.frames, "rss_checkpoint": at_checkpoint[0] if at_checkpoint else end,
            "rss_end": end, "ms": 1000 * float(np.nanmedian(times)) if frames > 1 else float("nan"),
            "cpu_ms": 1000 * float(np.nanmedian(cpu)) if frames > 1 else float("nan"),
            "lost": result.lost_frames}


def measure(name: str, case: str, frames: int, tmp: str) -> dict:
    """:func:`child` in a fresh process (its peak RSS is this run's alone)."""
    proc = subprocess.run([sys.executable, __file__, "--child", name, case, str(frames), f"{tmp}/boxes.txt"],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines()
        return {"failed": lines[-1] if lines else f"exit {proc.returncode}"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--filter", default="all", help="comma-separated tracker names (default: every registered one)")
    parser.add_argument("--cases", default="vga,4k,small,long", help=f"comma-separated cases of {', '.join(CASES)}")
    parser.add_argument("--frames", type=int, default=200, help="frames of the vga, 4k and small cases (default 200)")
    parser.add_argument("--long-frames", type=int, default=100_000,
                        help="frames of the long case (default 100000; RSS also read after 1000)")
    parser.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        name, case, frames, boxes = args.child
        print(json.dumps(child(name, case, int(frames), boxes)))
        return 0
    from vidtrack.api import filters

    names = list(filters()) if args.filter == "all" else [n for n in args.filter.split(",") if n]
    cases = [c for c in args.cases.split(",") if c]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        parser.error(f"unknown case {unknown[0]!r}; valid: {', '.join(CASES)}")
    print(f"frames per case: {args.frames} (long: {args.long_frames}); peak RSS in MB, tracker ms per frame (median)")
    cols = []
    for case in cases:
        cols += [f"{case} MB", f"{case} ms", f"{case} cpu ms"] if case != "long" else ["long MB @1000", "long MB end", "long end/@1000",
                                                                      "long ms"]
    print("| tracker | " + " | ".join(cols) + " | 4k/vga ms | 4k/vga cpu | checks |")
    print("|---|" + "---:|" * (len(cols) + 2) + "---|")
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            got = {c: measure(name, c, args.long_frames if c == "long" else args.frames, tmp) for c in cases}
            cells, problems = [], []
            for case in cases:
                r = got[case]
                if "refused" in r or "failed" in r:
                    cells += ["refused" if "refused" in r else "failed"] + ["-"] * 3
                    problems.append(f"{case}: {r.get('refused') or r.get('failed')}")
                    continue
                if case == "long":
                    growth = r["rss_end"] / r["rss_checkpoint"]
                    cells += [f"{r['rss_checkpoint']:.0f}", f"{r['rss_end']:.0f}", f"{growth:.3f}", f"{r['ms']:.2f}"]
                    if growth > GROWTH_LIMIT:
                        problems.append("long: RSS grew > 10 %")
                else:
                    cells += [f"{r['rss_end']:.0f}", f"{r['ms']:.1f}", f"{r['cpu_ms']:.1f}"]
                if r["rss_end"] > RSS_LIMIT_MB:
                    problems.append(f"{case}: RSS > 1 GB")
            ratio = cpu_ratio = "-"
            if all(c in got and "ms" in got[c] for c in ("vga", "4k")):
                ratio = f"{got['4k']['ms'] / got['vga']['ms']:.2f}"
                slow = got["4k"]["cpu_ms"] / got["vga"]["cpu_ms"]
                cpu_ratio = f"{slow:.2f}"
                if slow > SLOWDOWN_LIMIT:
                    problems.append("4k > 1.5x vga")
            failures += bool(problems)
            print(f"| {name} | " + " | ".join(cells) + f" | {ratio} | {cpu_ratio} | {'; '.join(problems) or 'ok'} |", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
