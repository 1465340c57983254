"""What the subcommands share: the one-line argument parser, tracker settings, the init box, messages, the progress bar.

Every user error is one line on stderr, ``vidtrack: error: MESSAGE``, and
exit code :data:`EXIT_USAGE`; the messages are those of the
:class:`~vidtrack.errors.VidtrackError` the Python API raises.

Tracker settings come in this order, a later one winning:

1. ``--config FILE.toml`` (:func:`vidtrack.config.read_toml`: tables are groups),
2. the shortcuts ``--model FILE`` (the setting ``model``) and ``--detector NAME``
   (the setting ``detector``),
3. every ``--set KEY=VALUE`` in the order given (dotted keys for groups,
   ``--set svr.C=2``).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
from contextlib import contextmanager
from typing import Any, Iterator, Sequence

from ..config import parse_setting, read_toml
from ..errors import UsageError
from ..types import Box

#: The subcommands beside ``vidtrack VIDEO`` (tracking): each is the module ``vidtrack.cli.<name>``.
SUBCOMMANDS = ("filters", "eval", "reproduce", "learn", "bench", "trax")

EXIT_OK = 0
EXIT_FAILED = 1          # a run finished but part of it failed (``vidtrack eval``: a tracker crashed)
EXIT_USAGE = 2           # bad input: one line on stderr
EXIT_INTERRUPTED = 130   # Ctrl-C (128 + SIGINT); a stopping signal N gives 128 + N (SIGTERM: 143)

#: Signals that stop a run the way Ctrl-C does: every output finished, exit 128 + N.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

DEFAULT_FILTER = "mil"
FALLBACK_FILTER = "kalman-cv"


def say(message: str) -> None:
    """A message of the ``vidtrack`` command on stderr (stdout carries results only)."""
    print(f"vidtrack: {message}", file=sys.stderr)


class Stopped(KeyboardInterrupt):
    """A stopping signal (:data:`STOP_SIGNALS`) raised where the main thread is, like Ctrl-C's KeyboardInterrupt.

    Parameters
    ----------
    signum
        The signal's number (``signal.SIGTERM`` ...).
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def signal_name(exc: BaseException) -> str:
    """``SIGTERM`` for a :class:`Stopped` by SIGTERM, ``SIGINT`` for any other KeyboardInterrupt."""
    return signal.Signals(getattr(exc, "signum", signal.SIGINT)).name


def interrupted_exit_code(signum: int | None) -> int:
    """128 + the signal's number (130 for SIGINT, 143 for SIGTERM); 130 when it is not known."""
    return 128 + int(signum if signum is not None else signal.SIGINT)


@contextmanager
def stop_signals_as_interrupt() -> Iterator[None]:
    """Within the block, SIGINT, SIGTERM and SIGHUP raise :class:`Stopped` in the main thread.

    So ``docker stop``, a scheduler's time limit or a closed terminal end a
    run the way Ctrl-C does: the code unwinding from the exception finishes
    every output.  Only the first signal raises; later ones are ignored while
    the outputs are being finished (``kill -9`` still stops at once), and a
    signal arriving while a frame is written to the sinks waits till it is
    written to all of them (:func:`vidtrack.sinks.base.defer_interrupt`).  The
    previous handlers are restored on leaving the block.  Outside the main
    thread this does nothing (Python delivers signals to the main thread only).
    """
    import threading

    from ..sinks.base import defer_interrupt

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def handler(signum, frame) -> None:
        if received:
            return
        received.append(signum)
        if not defer_interrupt(Stopped(signum)):
            raise Stopped(signum)

    previous = {number: signal.signal(number, handler) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, old in previous.items():
            signal.signal(number, old)


def error_line(message: str) -> str:
    """The one line a user error prints."""
    return f"vidtrack: error: {message}"


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are a single line on stderr, exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

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


def parse_init_box(text: str, option: str = "--init-box") -> Box:
    """``"x,y,w,h"`` -> :class:`~vidtrack.types.Box` (:meth:`Box.parse <vidtrack.types.Box.parse>`).

    Raises
    ------
    UsageError
        Unless the text is four finite numbers with a positive width and height.
    """
    try:
        box = Box.parse(text)
    except ValueError:
        raise UsageError(f"{option} must be four numbers x,y,w,h, got {text!r}") from None
    if not all(math.isfinite(v) for v in (box.x, box.y, box.w, box.h)):
        raise UsageError(f"{option} must be four finite numbers x,y,w,h, got {text!r}")
    if not box.is_valid():
        raise UsageError(f"{option} must have a positive width and height, got {text!r}")
    return box


def check_box_in_frame(frame, box: Box) -> None:
    """Reject an ``--init-box`` that does not lie mostly inside the first frame (:func:`vidtrack.api.check_inside`)."""
    from ..api import check_inside

    check_inside(box, frame.width, frame.height, what="--init-box")


def default_filter() -> str:
    """``mil``, or ``kalman-cv`` in a build without it."""
    from ..recipes import registry

    return DEFAULT_FILTER if DEFAULT_FILTER in registry() else FALLBACK_FILTER


def add_filter_argument(parser: argparse.ArgumentParser) -> None:
    """``--filter NAME`` (default: :func:`default_filter`)."""
    parser.add_argument("--filter", default=None, metavar="NAME",
                        help=f"tracker to use (default {DEFAULT_FILTER}); `vidtrack filters` lists them, "
                             f"`vidtrack filters NAME` its options")


def add_settings_arguments(parser: argparse.ArgumentParser) -> None:
    """``--config``, ``--model``, ``--detector`` and ``--set``: a tracker's options (see the module's order)."""
    group = parser.add_argument_group(
        "tracker options", "applied in this order: --config, then --model and --detector, then each --set")
    group.add_argument("--config", metavar="FILE.toml",
                       help="tracker options from a TOML file (a [table] is a group: [svr] then C = 2.0)")
    group.add_argument("--model", metavar="FILE", help="a learned model file for trackers that take one "
                                                       "(cbt): the option model")
    group.add_argument("--detector", metavar="NAME", help="detector of score-map trackers (e.g. face): "
                                                          "the option detector")
    group.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="settings",
                       help="set one tracker option (repeatable; dotted keys for groups: --set svr.C=2)")


def tracker_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The tracker settings (dotted key -> value) of ``args``: ``--config``, the shortcuts, each ``--set``.

    Raises
    ------
    UsageError
        For a missing or invalid TOML file or a ``--set`` without ``KEY=``.
    """
    settings: dict[str, Any] = {}

    def put(key: str, value: Any) -> None:
        settings.pop(key, None)   # re-inserted at the end: the dict's order is the order applied
        settings[key] = value

    if getattr(args, "config", None):
        for key, value in read_toml(args.config).items():
            put(key, value)
    if getattr(args, "model", None):
        put("model", args.model)
    if getattr(args, "detector", None):
        put("detector", args.detector)
    for text in getattr(args, "settings", None) or ():
        put(*parse_setting(text))
    return settings


def check_settings(name: str, settings: dict[str, Any]) -> None:
    """Fail now, in one line, for an unknown tracker ``name`` or a setting it does not take.

    Raises
    ------
    UsageError
        The message of :func:`vidtrack.api.tracker_config` (it names the
        tracker and lists its options).
    """
    from ..api import tracker_config

    tracker_config(name, settings)


def progress_bar(iterable=None, *, total=None, desc=None, quiet=False, unit="frame"):
    """A tqdm progress bar on stderr (frames, rate, ETA), or the bare iterable when quiet."""
    from tqdm import tqdm

    interactive = sys.stderr.isatty()
    # delay: no bar before the first second, so an error found at the first frame stays one line
    return tqdm(iterable, total=total, desc=desc, unit=unit, disable=quiet, file=sys.stderr,
                dynamic_ncols=True, leave=False, mininterval=0.2 if interactive else 10.0, delay=1.0)
