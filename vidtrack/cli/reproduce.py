"""``vidtrack reproduce NAME``: reproduce a table of one of the papers vidtrack implements.

``vidtrack reproduce`` (or ``--list``) lists the experiments
(:data:`vidtrack.experiments.EXPERIMENTS`); ``vidtrack reproduce NAME --help``
shows an experiment's own options; ``vidtrack reproduce all --out DIR`` runs
every experiment into one report.  The table goes to stdout, ``--json FILE``
writes the result as JSON.
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path
from typing import Sequence

from ..errors import UsageError
from .common import EXIT_OK, OneLineParser, progress_bar


def _progress(quiet: bool):
    """The progress callable the experiments take: ``progress(iterable=None, **tqdm_options)``."""
    return lambda it=None, **kw: progress_bar(it, quiet=quiet, unit="run", **kw)


def list_experiments(experiments: dict[str, str]) -> None:
    """One ``name  description`` line per experiment, then ``all``."""
    for name, module_name in experiments.items():
        try:
            description = importlib.import_module(module_name).DESCRIPTION
        except ModuleNotFoundError:
            description = "(not available in this build)"
        print(f"{name:<16} {description}")
    print(f"{'all':<16} every experiment into one report: vidtrack reproduce all --out DIR")


def main(argv: Sequence[str]) -> int:
    """``vidtrack reproduce ...``: exit 0, or 2 on bad input."""
    from ..experiments import EXPERIMENTS

    parser = OneLineParser(prog="vidtrack reproduce", add_help=False,
                           description="Reproduce a table of one of the papers vidtrack implements; "
                                       "`vidtrack reproduce NAME --help` shows the experiment's options.")
    parser.add_argument("name", nargs="?", help=f"experiment: {', '.join(EXPERIMENTS)}")
    parser.add_argument("--list", action="store_true", help="list the experiments")
    parser.add_argument("-h", "--help", action="store_true", help="show this help message and exit")
    known, rest = parser.parse_known_args(argv)
    if known.help and not known.name:
        parser.print_help()
        return EXIT_OK
    if known.help:
        rest = [*rest, "--help"]   # the experiment's own parser lists its options
    if known.list or not known.name:
        list_experiments(EXPERIMENTS)
        return EXIT_OK
    if known.name == "all":
        from ..experiments import report

        sub = OneLineParser(prog="vidtrack reproduce all", description=report.DESCRIPTION)
        report.add_arguments(sub)
        args = sub.parse_args(rest)
        path = report.run_all(args, _progress(args.quiet))
        print(f"wrote {path}", file=sys.stderr)
        return EXIT_OK
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
        from ..sinks.base import open_text_output

        json_out = open_text_output(args.json)  # fail before a long run, not after
    try:
        result = module.run(args, _progress(args.quiet))
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
    return EXIT_OK
