"""The ``vidtrack`` command line.

``vidtrack VIDEO --init-box x,y,w,h --filter NAME [options]`` tracks a video;
subcommands stand beside it: ``filters``, ``eval``, ``reproduce``, ``learn``,
``bench`` and ``trax``.  Every user error prints one line on stderr and exits with 2.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path
from typing import Sequence

from . import __version__
from .errors import UsageError, VidtrackError

#: Subcommands implemented in other modules: name -> module with ``main(argv) -> int``.
EXTERNAL_SUBCOMMANDS = {
    "eval": "vidtrack.eval.cli",
    "learn": "vidtrack.learn_cli",
    "bench": "vidtrack.bench",
    "trax": "vidtrack.trax_server",
}
SUBCOMMANDS = ("filters", "reproduce", *EXTERNAL_SUBCOMMANDS)
DEFAULT_FILTER = "mil"
FALLBACK_FILTER = "kalman-cv"


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are a single line on stderr, exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        return super().parse_known_args(join_negative_values(sys.argv[1:] if args is None else args), namespace)


#: Options whose value may start with a minus sign (a box partly left of or above the frame).
NEGATIVE_VALUE_OPTIONS = ("--init-box",)
_NEGATIVE_STARTS = {f"-{c}" for c in "0123456789."}


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """``["--init-box", "-5,20,31,45"]`` -> ``["--init-box=-5,20,31,45"]``.

    argparse takes a value starting with ``-`` for an option, so the plain
    form would fail with "expected one argument" while ``--init-box=-5,...``
    works; this makes both work.
    """
    argv, out, i = list(argv), [], 0
    while i < len(argv):
        if argv[i] in NEGATIVE_VALUE_OPTIONS and i + 1 < len(argv) and argv[i + 1][:2] in _NEGATIVE_STARTS:
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def parse_box(text: str):
    """``"x,y,w,h"`` -> :class:`~vidtrack.types.Box`; positive size required."""
    from .types import Box

    parts = [p for p in text.replace(" ", ",").split(",") if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"--init-box must be four numbers x,y,w,h, got {text!r}") from None
    if len(values) != 4:
        raise UsageError(f"--init-box must be four numbers x,y,w,h, got {text!r}")
    if not all(math.isfinite(v) for v in values):
        raise UsageError(f"--init-box must be four finite numbers x,y,w,h, got {text!r}")
    box = Box.from_array(values)
    if not box.is_valid():
        raise UsageError(f"--init-box must have a positive width and height, got {text!r}")
    return box


def check_box_in_frame(frame, box) -> None:
    """Reject an init box that is not (mostly) inside the first frame."""
    inside = box.clipped(frame.width, frame.height)
    if inside.area < 0.5 * box.area:
        raise UsageError(f"--init-box {box} lies outside the {frame.width}x{frame.height} frame")


def default_filter() -> str:
    from .recipes import registry

    return DEFAULT_FILTER if DEFAULT_FILTER in registry() else FALLBACK_FILTER


def progress_bar(iterable=None, *, total=None, desc=None, quiet=False, unit="frame"):
    """A tqdm progress bar on stderr (frames, rate, ETA), or the bare iterable when quiet."""
    from tqdm import tqdm

    interactive = sys.stderr.isatty()
    # delay: no bar before the first second, so an error found at the first frame stays one line
    return tqdm(iterable, total=total, desc=desc, unit=unit, disable=quiet, file=sys.stderr,
                dynamic_ncols=True, leave=False, mininterval=0.2 if interactive else 10.0, delay=1.0)


# ---------------------------------------------------------------- track


def build_track_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="vidtrack",
        description="Track an object through a video with a robust filter. "
                    f"Subcommands: {', '.join(SUBCOMMANDS)} (vidtrack SUBCOMMAND --help).",
    )
    parser.add_argument("video", help="video file (mp4, avi, webm ...) or folder of frame images")
    parser.add_argument("--init-box", required=True, metavar="x,y,w,h",
                        help="the object's box in the first frame, 0-based pixels")
    parser.add_argument("--filter", default=None, metavar="NAME",
                        help=f"tracker to use (default {DEFAULT_FILTER}); `vidtrack filters` lists them")
    parser.add_argument("-o", "--output", metavar="FILE.mp4", help="write the annotated video here")
    parser.add_argument("--boxes", metavar="FILE", help="write one x,y,w,h line per frame here")
    parser.add_argument("--log", metavar="FILE.csv", help="write frame,x,y,w,h,confidence,status per frame")
    parser.add_argument("--rerun", metavar="FILE.rrd", help="write a Rerun recording of every stage")
    parser.add_argument("--rerun-spawn", action="store_true", help="also show the recording in a Rerun viewer")
    parser.add_argument("--flush-every", type=int, default=30, metavar="N",
                        help="frames per fragment of the annotated video and per batch of the Rerun "
                             "recording (default 30): after a hard stop at most N frames are missing")
    parser.add_argument("--model", metavar="FILE", help="a learned model file for filters that take one (cbt)")
    parser.add_argument("--detector", metavar="NAME", help="detector for score-map filters (e.g. face)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    parser.add_argument("--version", action="version", version=f"vidtrack {__version__}")
    return parser


def tracker_options(args: argparse.Namespace) -> dict:
    """Recipe overrides from the CLI (only those given)."""
    options = {}
    if getattr(args, "model", None):
        options["model"] = args.model
    if getattr(args, "detector", None):
        options["detector"] = args.detector
    return options


def run_track(argv: Sequence[str]) -> int:
    from .run import run_tracker
    from .sinks.base import close_and_remove
    from .sinks.files import BoxesSink, CsvLogSink
    from .sinks.video import AnnotatedVideoSink
    from .sources import open_source
    from .recipes import build_tracker

    args = build_track_parser().parse_args(argv)
    init_box = parse_box(args.init_box)
    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError("--max-frames must be at least 1")
    if args.flush_every < 1:
        raise UsageError("--flush-every must be at least 1")
    name = args.filter or default_filter()
    tracker = build_tracker(name, seed=args.seed, **tracker_options(args))
    source = open_source(args.video)

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
            from .sinks.rerun import RerunSink

            sinks.append(RerunSink(args.rerun, filter_name=name, spawn=args.rerun_spawn,
                                   batch_frames=args.flush_every))
    except VidtrackError:
        close_and_remove(sinks)  # no empty boxes file beside an unwritable video
        raise

    total = len(source) or None
    if args.max_frames is not None and total is not None:
        total = min(total, args.max_frames)
    bar = progress_bar(total=total, desc=name, quiet=args.quiet)
    try:
        result = run_tracker(tracker, source, init_box, sinks, max_frames=args.max_frames,
                             on_state=lambda state: bar.update(1), validate_box=check_box_in_frame)
    finally:
        bar.close()
    written = [str(s.path) for s in sinks if getattr(s, "path", None)]
    if not args.quiet:
        print(f"vidtrack: {name} tracked {result.frames} frames at {result.fps:.1f} fps, "
              f"lost in {result.lost_frames}" + (f"; wrote {', '.join(written)}" if written else ""),
              file=sys.stderr)
    if result.interrupted:
        print(f"vidtrack: interrupted after {result.frames} frames; outputs keep every tracked frame",
              file=sys.stderr)
        return 130
    if result.decode_error:
        print(f"vidtrack: error: {result.decode_error}; kept the {result.frames} frames tracked", file=sys.stderr)
        return 2
    return 0


# ---------------------------------------------------------------- filters


def run_filters(argv: Sequence[str]) -> int:
    from .recipes import registry

    parser = OneLineParser(prog="vidtrack filters", description="List every registered filter.")
    parser.parse_args(argv)
    recipes = registry()
    width = max(len(name) for name in recipes)
    for name in sorted(recipes):
        print(f"{name:<{width}}  {recipes[name].description}")
    return 0


# ---------------------------------------------------------------- reproduce


def run_reproduce(argv: Sequence[str]) -> int:
    from .experiments import EXPERIMENTS

    parser = OneLineParser(prog="vidtrack reproduce", add_help=False,
                           description="Reproduce a table of one of the papers vidtrack implements; "
                                       "`vidtrack reproduce NAME --help` shows the experiment's options.")
    parser.add_argument("name", nargs="?", help=f"experiment: {', '.join(EXPERIMENTS)}")
    parser.add_argument("--list", action="store_true", help="list the experiments")
    parser.add_argument("-h", "--help", action="store_true", help="show this help message and exit")
    known, rest = parser.parse_known_args(argv)
    if known.help and not known.name:
        parser.print_help()
        return 0
    if known.help:
        rest = [*rest, "--help"]   # the experiment's own parser lists its options
    if known.list or not known.name:
        for name, module_name in EXPERIMENTS.items():
            try:
                description = importlib.import_module(module_name).DESCRIPTION
            except ModuleNotFoundError:
                description = "(not available in this build)"
            print(f"{name:<16} {description}")
        print(f"{'all':<16} every experiment into one report: vidtrack reproduce all --out DIR")
        return 0
    if known.name == "all":
        from .experiments import report

        sub = OneLineParser(prog="vidtrack reproduce all", description=report.DESCRIPTION)
        report.add_arguments(sub)
        args = sub.parse_args(rest)
        path = report.run_all(args, lambda it=None, **kw: progress_bar(it, quiet=args.quiet, unit="run", **kw))
        print(f"wrote {path}", file=sys.stderr)
        return 0
    if known.name not in EXPERIMENTS:
        raise UsageError(f"unknown experiment {known.name!r}; valid: {', '.join(EXPERIMENTS)}")
    module = importlib.import_module(EXPERIMENTS[known.name])
    sub = OneLineParser(prog=f"vidtrack reproduce {known.name}", description=module.DESCRIPTION)
    sub.add_argument("--runs", type=int, default=None, help="number of simulation runs")
    sub.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    sub.add_argument("--json", metavar="FILE", help="write the result as JSON here")
    sub.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    module.add_arguments(sub)
    args = sub.parse_args(rest)
    args.experiment = known.name
    if args.runs is not None and args.runs < 1:
        raise UsageError("--runs must be at least 1")
    json_out = None
    if args.json:
        from .sinks.base import open_text_output

        json_out = open_text_output(args.json)  # fail before a long run, not after
    try:
        result = module.run(args, lambda it=None, **kw: progress_bar(it, quiet=args.quiet, unit="run", **kw))
    except BaseException:
        if json_out is not None:  # no empty JSON file after a failed run
            json_out.close()
            Path(args.json).unlink(missing_ok=True)
        raise
    print(module.format_table(result))
    if json_out is not None:
        json.dump(result, json_out, indent=2)
        json_out.write("\n")
        json_out.close()
        print(f"wrote {args.json}", file=sys.stderr)
    return 0


# ---------------------------------------------------------------- main


def dispatch(argv: Sequence[str]) -> int:
    if argv and argv[0] == "filters":
        return run_filters(argv[1:])
    if argv and argv[0] == "reproduce":
        return run_reproduce(argv[1:])
    if argv and argv[0] in EXTERNAL_SUBCOMMANDS:
        module_name = EXTERNAL_SUBCOMMANDS[argv[0]]
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                raise UsageError(f"'vidtrack {argv[0]}' is not available in this build") from None
            raise
        return module.main(list(argv[1:]))
    return run_track(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``vidtrack`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        return dispatch(argv)
    except VidtrackError as exc:
        print(f"vidtrack: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("vidtrack: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
