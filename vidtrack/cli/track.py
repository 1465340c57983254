"""``vidtrack VIDEO --init-box x,y,w,h [--filter NAME] [options]``: track one object through a video.

VIDEO may also be a camera index, a stream URL or ``-`` (stdin), read live
(:mod:`vidtrack.cli.live`): a stream that stops part-way and cannot be
reopened ends the run with one line and exit 1, every output kept.

Writes any of: the annotated video (``-o``), one box per frame (``--boxes``),
a per-frame CSV log (``--log``) and a Rerun recording (``--rerun``).  Exit 0,
also when a frame in the middle does not decode (a warning names it; the
tracker predicts through it) or the video stops decoding part way (a warning;
every frame tracked is kept); 1 when an output fails part-way (a full disk:
one line, every file valid up to its last complete write); 2 on bad input
(one line); 128 + N after a
stopping signal N: 130 for Ctrl-C (SIGINT), 143 for SIGTERM, every output
finished with every frame tracked.
"""

from __future__ import annotations

import argparse
import signal
import sys
from typing import Sequence

from ..errors import UsageError, VidtrackError
from ..version import __version__
from .common import (EXIT_FAILED, EXIT_OK, SUBCOMMANDS, OneLineParser, add_filter_argument, add_settings_arguments,
                     check_box_in_frame, check_settings, default_filter, error_line, interrupted_exit_code, parse_init_box, progress_bar, say, tracker_settings)
from .live import INPUT_HELP, LiveMonitor, add_live_arguments, close_source, is_live, open_frames, stream_failure


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="vidtrack",
        description="Track an object through a video with a robust filter. "
                    f"Subcommands: {', '.join(SUBCOMMANDS)} (vidtrack SUBCOMMAND --help).",
    )
    parser.add_argument("video", help=INPUT_HELP)
    parser.add_argument("--init-box", required=True, metavar="x,y,w,h",
                        help="the object's box in the first frame, 0-based pixels")
    add_filter_argument(parser)
    parser.add_argument("-o", "--output", metavar="FILE.mp4", help="write the annotated video here")
    parser.add_argument("--boxes", metavar="FILE", help="write one x,y,w,h line per frame here")
    parser.add_argument("--log", metavar="FILE.csv", help="write frame,x,y,w,h,confidence,status per frame")
    parser.add_argument("--rerun", metavar="FILE.rrd", help="write a Rerun recording of every stage")
    parser.add_argument("--rerun-spawn", action="store_true", help="also show the recording in a Rerun viewer")
    parser.add_argument("--flush-every", type=int, default=30, metavar="N",
                        help="frames per fragment of the annotated video and per batch of the Rerun "
                             "recording (default 30): after a hard stop at most N frames are missing")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    parser.add_argument("--version", action="version", version=f"vidtrack {__version__}")
    add_settings_arguments(parser)
    add_live_arguments(parser)
    return parser


def main(argv: Sequence[str]) -> int:
    """``vidtrack VIDEO ...``: the exit code."""
    from ..recipes import build_tracker
    from ..run import run_tracker
    from ..sinks.base import close_and_remove
    from ..sinks.files import BoxesSink, CsvLogSink
    from ..sinks.video import AnnotatedVideoSink

    args = build_parser().parse_args(argv)
    init_box = parse_init_box(args.init_box)
    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError("--max-frames must be at least 1")
    if args.flush_every < 1:
        raise UsageError("--flush-every must be at least 1")
    name = args.filter or default_filter()
    settings = tracker_settings(args)
    check_settings(name, settings)
    tracker = build_tracker(name, seed=args.seed, settings=settings)
    source = open_frames(args)
    source.on_skip = lambda message: say(f"warning: {message}; the tracker predicts through")

    sinks = []
    try:
        if args.boxes:
            sinks.append(BoxesSink(args.boxes))
        if args.log:
            sinks.append(CsvLogSink(args.log))
        if args.output:
            sinks.append(AnnotatedVideoSink(args.output, filter_name=name, fps=source.fps,
                                            batch=args.flush_every))
        if args.rerun or args.rerun_spawn:
            from ..sinks.rerun import RerunSink

            sinks.append(RerunSink(args.rerun, filter_name=name, spawn=args.rerun_spawn,
                                   batch_frames=args.flush_every))
    except VidtrackError:
        close_and_remove(sinks)  # no empty boxes file beside an unwritable video
        close_source(source)
        raise

    total = len(source) or None
    if args.max_frames is not None and total is not None:
        total = min(total, args.max_frames)
    bar = progress_bar(total=total, desc=name, quiet=args.quiet)
    monitor = LiveMonitor(source)

    def on_state(state) -> None:
        monitor.on_state(state)
        bar.update(1)

    try:
        result = run_tracker(tracker, source, init_box, sinks, max_frames=args.max_frames,
                             on_state=on_state, validate_box=check_box_in_frame)
    finally:
        bar.close()
        close_source(source)
    written = [str(s.path) for s in sinks if getattr(s, "path", None)]
    if not args.quiet:
        say(f"{name} tracked {result.frames} frames at {result.fps:.1f} fps, lost in {result.lost_frames}"
            + (f", {len(result.skipped)} undecodable skipped" if result.skipped else "")
            + (f"; wrote {', '.join(written)}" if written else ""))
        if is_live(source):
            say(monitor.line(result.frames))
    if result.interrupted:
        name = signal.Signals(result.signum or signal.SIGINT).name
        say(f"interrupted after {result.frames} frames ({name}); outputs keep every tracked frame")
        return interrupted_exit_code(result.signum)
    if result.output_error is not None:   # a full disk: every output holds the frames written before it
        print(error_line(f"{result.output_error}; the outputs keep the {result.frames} frames written before"),
              file=sys.stderr)
        return EXIT_FAILED
    if stream_failure(source):   # a stream that stalled or broke and could not be reopened
        print(error_line(f"{stream_failure(source)}; the outputs keep the {result.frames} frames tracked"),
              file=sys.stderr)
        return EXIT_FAILED
    if result.decode_error:  # a video cut short: what was tracked is the result
        say(f"warning: {result.decode_error}; kept the {result.frames} frames tracked")
    return EXIT_OK

