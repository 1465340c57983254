"""The ``vidtrack`` command line: one module per subcommand.

``vidtrack VIDEO --init-box x,y,w,h --filter NAME [options]`` tracks a video
(:mod:`~vidtrack.cli.track`); the subcommands stand beside it:
``filters`` (:mod:`~vidtrack.cli.filters`), ``eval`` (:mod:`~vidtrack.cli.eval`),
``reproduce`` (:mod:`~vidtrack.cli.reproduce`), ``learn`` (:mod:`~vidtrack.cli.learn`),
``bench`` (:mod:`~vidtrack.cli.bench`) and ``trax`` (:mod:`~vidtrack.cli.trax`);
:mod:`~vidtrack.cli.common` holds what they share.  Every user error prints one
line on stderr and exits with 2.  Nothing outside this package imports it: the
Python entry point is :mod:`vidtrack.api`.
"""

from __future__ import annotations

import importlib
import sys
from typing import Sequence

from ..errors import UsageError, VidtrackError
from ..sinks.base import WriteFailed
from .common import (EXIT_FAILED, EXIT_OK, EXIT_USAGE, SUBCOMMANDS, error_line, interrupted_exit_code, say, signal_name,
                     stop_signals_as_interrupt)

__all__ = ["main"]


def dispatch(argv: Sequence[str]) -> int:
    """Run the subcommand ``argv[0]`` names, else track (``vidtrack VIDEO ...``)."""
    name = argv[0] if argv and argv[0] in SUBCOMMANDS else "track"
    module_name = f"{__name__}.{name}"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            raise UsageError(f"'vidtrack {name}' is not available in this build") from None
        raise
    return module.main(list(argv[1:] if name != "track" else argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``vidtrack`` console script: the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        with stop_signals_as_interrupt():
            return dispatch(argv)
    except WriteFailed as exc:   # a full disk part-way: not the user's input
        print(error_line(str(exc)), file=sys.stderr)
        return EXIT_FAILED
    except VidtrackError as exc:
        print(error_line(str(exc)), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:
        say(f"interrupted ({signal_name(exc)}); every finished output is kept")
        return interrupted_exit_code(getattr(exc, "signum", None))
    except BrokenPipeError:
        return EXIT_OK
