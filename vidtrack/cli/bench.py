"""``vidtrack bench``: per-stage time per frame of a tracker, so the next optimisation is visible.

Stages: ``decode`` (reading the frame), the measurer's own stages (for the
MIL filter ``superpixels``, ``features``, ``svm``, ``graphcut``; a measurer
reports them in a ``timings_`` dict of accumulated seconds), ``measure
(other)`` (measurer time not in a named stage), ``filter`` (predict +
update) and ``learn (other)`` (time in ``learn`` not in a named stage).
A measurer that runs a stage in a second thread (``mil``'s correlation
filter) reports it in ``cf_timings_``; those are printed apart, since
they overlap the others, and the main thread's wait for them is its own stage.
The tracker options are set as for tracking (``--config``, ``--set`` ...).

``--targets 1,2,4`` times several targets instead (boxes from repeated
``--init-box`` or ``--init-boxes FILE``, the first N by ID for a count N):
for each count, the wall-clock and CPU time per frame of all the targets
together (:class:`~vidtrack.targets.MultiTargetTracker`, one thread per
target up to the number of CPUs), the fps, and the cost relative to one target.
"""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from typing import Sequence

from ..errors import UsageError
from .common import (EXIT_OK, OneLineParser, add_filter_argument, add_settings_arguments, check_box_in_frame,
                     check_settings, default_filter, tracker_settings)
from .init_boxes import add_init_box_arguments, boxes_in_frame, init_boxes


def build_parser() -> OneLineParser:
    parser = OneLineParser(prog="vidtrack bench",
                           description="Time every stage of a tracker per frame on a video or frame folder.")
    parser.add_argument("video", help="video file or folder of frame images")
    add_init_box_arguments(parser)
    parser.add_argument("--targets", metavar="N,N,...",
                        help="time these numbers of targets (the first N boxes by ID), e.g. 1,2,4")
    add_filter_argument(parser)
    parser.add_argument("--max-frames", type=int, default=300, metavar="N", help="frames to time (default 300)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_settings_arguments(parser)
    return parser


def main(argv: Sequence[str]) -> int:
    """``vidtrack bench VIDEO --init-box ...``: the table on stdout, exit 0 (2 on bad input)."""
    from ..recipes import build_tracker
    from ..sources import open_source

    args = build_parser().parse_args(list(argv))
    if args.max_frames < 2:
        raise UsageError("--max-frames must be at least 2")
    boxes, box_names = init_boxes(args)
    name = args.filter or default_filter()
    settings = tracker_settings(args)
    check_settings(name, settings)
    if args.targets is not None:
        return bench_targets(args, name, settings, boxes, box_names)
    box = boxes[min(boxes)]
    tracker = build_tracker(name, seed=args.seed, settings=settings)
    source = iter(open_source(args.video))
    totals: dict[str, float] = defaultdict(float)
    frames = 0
    t0 = time.perf_counter()
    first = next(source, None)
    if first is None:
        raise UsageError(f"{args.video} holds no frames")
    totals["decode"] += time.perf_counter() - t0
    check_box_in_frame(first, box)
    tracker.initialize(first, box)
    measurer, filt = tracker.measurer, tracker.filter
    timed = getattr(measurer, "inner", measurer)   # a wrapped measurer's stages are its inner one's
    stage_time = getattr(timed, "timings_", None)
    background = getattr(timed, "cf_timings_", None)
    for timings in (stage_time, background):
        if timings is not None:
            timings.clear()  # time the steady state, not the bootstrap
    wall = 0.0
    cpu = 0.0
    while frames < args.max_frames - 1:
        t = time.perf_counter()
        frame = next(source, None)
        totals["decode"] += time.perf_counter() - t
        if frame is None:
            break
        start = time.perf_counter()
        cpu_start = time.process_time()
        named_before = sum(stage_time.values()) if stage_time is not None else 0.0
        t = time.perf_counter()
        prior = filt.predict()
        totals["filter"] += time.perf_counter() - t
        t = time.perf_counter()
        measurement = measurer.measure(frame, prior)
        measure_s = time.perf_counter() - t
        named_mid = sum(stage_time.values()) if stage_time is not None else 0.0
        totals["measure (other)"] += measure_s - (named_mid - named_before)
        t = time.perf_counter()
        posterior = filt.update(measurement)
        totals["filter"] += time.perf_counter() - t
        t = time.perf_counter()
        measurer.learn(frame, posterior)
        learn_s = time.perf_counter() - t
        named_after = sum(stage_time.values()) if stage_time is not None else 0.0
        totals["learn (other)"] += learn_s - (named_after - named_mid)
        wall += time.perf_counter() - start
        cpu += time.process_time() - cpu_start
        frames += 1
    if frames == 0:
        raise UsageError("need at least two frames to benchmark")
    if stage_time is not None:
        totals.update(stage_time)
    order = ["decode", "superpixels", "features", "svm", "graphcut", "measure (other)", "filter", "learn (other)"]
    names = [n for n in order if n in totals] + sorted(n for n in totals if n not in order)
    print(f"vidtrack bench: {name} on {args.video}, {frames} frames after the first")
    print(f"{'stage':<16}{'ms/frame':>10}{'share':>8}")
    total_ms = sum(totals.values()) / frames * 1000
    for name in names:
        ms = totals[name] / frames * 1000
        print(f"{name:<20}{ms:>6.2f}{ms / total_ms * 100:>7.1f}%")
    print(f"{'total':<16}{total_ms:>10.2f}")
    if background:
        print("in a second thread, overlapping the stages above:")
        for name in sorted(background):
            print(f"{name:<16}{background[name] / frames * 1000:>10.2f}")
    print(f"tracking fps (decode excluded): {frames / wall:.1f}")
    # on a shared machine the wall clock also counts other processes' turns; the CPU time does not
    print(f"tracking fps by this process's CPU time: {frames / max(cpu, 1e-9):.1f}")
    sys.stdout.flush()
    return EXIT_OK


def target_counts(text: str, available: int) -> list[int]:
    """``"1,2,4"`` -> ``[1, 2, 4]``: positive counts, each at most ``available`` (the boxes given)."""
    try:
        counts = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise UsageError(f"--targets must be counts like 1,2,4, got {text!r}") from None
    if not counts or min(counts) < 1:
        raise UsageError(f"--targets must be positive counts like 1,2,4, got {text!r}")
    if max(counts) > available:
        raise UsageError(f"--targets {max(counts)} needs {max(counts)} boxes, {available} given "
                         f"(repeat --init-box or use --init-boxes)")
    return counts


def bench_targets(args, name: str, settings: dict, boxes: dict, box_names: dict) -> int:
    """Time ``name`` on the first N targets for each count N of ``--targets``; the table on stdout."""
    from ..recipes import build_tracker
    from ..sources import open_source
    from ..targets import MultiTargetTracker

    counts = target_counts(args.targets, len(boxes))
    rows = []
    for count in counts:
        chosen = {i: boxes[i] for i in sorted(boxes)[:count]}
        multi = MultiTargetTracker({i: build_tracker(name, seed=args.seed, settings=settings) for i in chosen})
        source = iter(open_source(args.video))
        first = next(source, None)
        if first is None:
            raise UsageError(f"{args.video} holds no frames")
        boxes_in_frame(box_names)(first, chosen)
        frames = wall = cpu = 0.0
        try:
            multi.initialize(first, chosen)
            for frame in source:
                if frames >= args.max_frames - 1:
                    break
                start, cpu_start = time.perf_counter(), time.process_time()
                multi.step(frame)
                wall += time.perf_counter() - start
                cpu += time.process_time() - cpu_start
                frames += 1
        finally:
            multi.close()
        if frames == 0:
            raise UsageError("need at least two frames to benchmark")
        rows.append((count, int(frames), wall / frames, cpu / frames))
    print(f"vidtrack bench: {name} on {args.video}, targets {','.join(map(str, counts))}")
    print(f"{'targets':>7}{'frames':>8}{'ms/frame':>10}{'fps':>8}{'CPU ms':>9}{'fps by CPU':>12}{'x one':>7}")
    one = next((wall for count, _, wall, _ in rows if count == 1), None)
    for count, frames, wall, cpu in rows:
        relative = f"{wall / one:>7.2f}" if one else f"{'':>7}"
        print(f"{count:>7}{frames:>8}{wall * 1000:>10.1f}{1 / wall:>8.1f}{cpu * 1000:>9.1f}{1 / max(cpu, 1e-9):>12.1f}"
              f"{relative}")
    sys.stdout.flush()
    return EXIT_OK
