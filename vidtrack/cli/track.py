"""``vidtrack VIDEO --init-box x,y,w,h [--filter NAME] [options]``: track objects through a video.

One target per ``--init-box`` (repeatable: IDs 1, 2 ...) or per line of
``--init-boxes FILE`` (``id,x,y,w,h``); several targets are tracked side by
side (:class:`~vidtrack.targets.MultiTargetTracker`).  Writes any of: the
annotated video (``-o``), the boxes (``--boxes``: one ``x,y,w,h`` per frame,
MOT Challenge lines with several targets), a per-frame CSV log (``--log``)
and a Rerun recording (``--rerun``).  VIDEO may also be a camera index, a
stream URL or ``-`` (stdin), read live (:mod:`vidtrack.cli.live`): a stream
that stops part-way and cannot be reopened ends the run with one line and
exit 1, every output kept.  Exit 0,
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
from typing import TYPE_CHECKING, Sequence

from ..errors import UsageError, VidtrackError
from ..version import __version__
from .common import (EXIT_FAILED, EXIT_OK, SUBCOMMANDS, OneLineParser, add_filter_argument, add_settings_arguments,
                     check_settings, default_filter, error_line, interrupted_exit_code, progress_bar, say,
                     tracker_settings)
from ..sinks.exports import EXPORT_FORMATS
from .init_boxes import add_init_box_arguments, boxes_in_frame, init_boxes
from .live import INPUT_HELP, LiveMonitor, add_live_arguments, close_source, is_live, open_frames, stream_failure

if TYPE_CHECKING:
    from ..targets import MultiTargetTracker


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="vidtrack",
        description="Track an object through a video with a robust filter. "
                    f"Subcommands: {', '.join(SUBCOMMANDS)} (vidtrack SUBCOMMAND --help).",
    )
    parser.add_argument("video", help=INPUT_HELP)
    add_init_box_arguments(parser)
    add_filter_argument(parser)
    parser.add_argument("-o", "--output", metavar="FILE.mp4", help="write the annotated video here")
    parser.add_argument("--boxes", metavar="FILE", help="write one x,y,w,h line per frame here (several targets: "
                                                        "MOT Challenge lines frame,id,x,y,w,h,confidence,-1,-1,-1)")
    parser.add_argument("--log", metavar="FILE.csv",
                        help="write frame,id,timestamp,x,y,w,h,confidence,status per target and frame")
    parser.add_argument("--export", metavar="FILE", help="write the tracks for an annotation tool: .xml CVAT for "
                                                         "video 1.1, .txt MOT Challenge, .jsonl JSON lines")
    parser.add_argument("--export-format", choices=EXPORT_FORMATS,
                        help="the --export format when its extension does not say it")
    parser.add_argument("--rerun", metavar="FILE.rrd", help="write a Rerun recording of every stage")
    parser.add_argument("--rerun-spawn", action="store_true", help="also show the recording in a Rerun viewer")
    parser.add_argument("--flush-every", type=int, default=30, metavar="N",
                        help="frames per fragment of the annotated video and per batch of the Rerun "
                             "recording (default 30): after a hard stop at most N frames are missing")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    parser.add_argument("--version", action="version", version=f"vidtrack {__version__}")
    add_live_arguments(parser)
    add_settings_arguments(parser)
    return parser


def build_sinks(args: argparse.Namespace, name: str, source) -> list:
    """The sinks the options ask for; none left behind when one cannot be opened."""
    from ..sinks.base import close_and_remove
    from ..sinks.files import BoxesSink, CsvLogSink
    from ..sinks.video import AnnotatedVideoSink

    sinks = []
    try:
        if args.boxes:
            sinks.append(BoxesSink(args.boxes))
        if args.log:
            sinks.append(CsvLogSink(args.log))
        if args.output:
            sinks.append(AnnotatedVideoSink(args.output, filter_name=name, fps=source.fps,
                                            batch=args.flush_every))
        if args.export:
            from ..sinks.exports import export_format, open_export

            sinks.append(open_export(args.export, export_format(args.export, args.export_format),
                                     filter_name=name, batch=args.flush_every))
        if args.rerun or args.rerun_spawn:
            from ..sinks.rerun import RerunSink

            sinks.append(RerunSink(args.rerun, filter_name=name, spawn=args.rerun_spawn,
                                   batch_frames=args.flush_every))
    except VidtrackError:
        close_and_remove(sinks)  # no empty boxes file beside an unwritable video
        close_source(source)
        raise
    return sinks


def build_targets(name: str, seed: int, settings: dict, ids) -> "MultiTargetTracker":
    """One tracker ``name`` per target ID, all with ``seed`` and ``settings``."""
    from ..recipes import build_tracker
    from ..targets import MultiTargetTracker

    return MultiTargetTracker({i: build_tracker(name, seed=seed, settings=settings) for i in ids})


def run_summary(name: str, result, targets: int, written: list[str]) -> str:
    """The summary line of a finished run."""
    what = f"{result.frames} frames" if targets == 1 else f"{targets} targets through {result.frames} frames"
    lost = f"lost in {result.lost_frames}" if targets == 1 else f"lost in {result.lost_frames} target-frames"
    return (f"{name} tracked {what} at {result.fps:.1f} fps, {lost}"
            + (f", {len(result.skipped)} undecodable skipped" if result.skipped else "")
            + (f"; wrote {', '.join(written)}" if written else ""))


def main(argv: Sequence[str]) -> int:
    """``vidtrack VIDEO ...``: the exit code."""
    from ..run import run_targets

    args = build_parser().parse_args(argv)
    boxes, box_names = init_boxes(args)
    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError("--max-frames must be at least 1")
    if args.flush_every < 1:
        raise UsageError("--flush-every must be at least 1")
    name = args.filter or default_filter()
    settings = tracker_settings(args)
    check_settings(name, settings)
    multi = build_targets(name, args.seed, settings, boxes)
    source = open_frames(args)
    source.on_skip = lambda message: say(f"warning: {message}; the tracker predicts through")
    sinks = build_sinks(args, name, source)

    total = len(source) or None
    if args.max_frames is not None and total is not None:
        total = min(total, args.max_frames)
    bar = progress_bar(total=total, desc=name, quiet=args.quiet)
    monitor = LiveMonitor(source)

    def on_frame(frame, targets) -> None:
        monitor.record(frame.arrival)
        bar.update(1)

    try:
        result = run_targets(multi, source, boxes, sinks, max_frames=args.max_frames,
                             on_frame=on_frame,
                             validate_boxes=boxes_in_frame(box_names))
    finally:
        bar.close()
        close_source(source)
    written = [str(s.path) for s in sinks if getattr(s, "path", None)]
    if not args.quiet:
        say(run_summary(name, result, len(boxes), written))
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
