"""``vidtrack eval DATASET_DIR --filter a,b,c``: run trackers on benchmark sequences and score them.

``vidtrack eval --compare DIR_A DIR_B`` tables the change in AUC between two such evaluations.
The tracker options (``--config``, ``--set`` ...) apply to every tracker listed
(:mod:`vidtrack.cli.common`); the evaluation itself is :mod:`vidtrack.eval`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import DatasetError, UsageError
from .common import (EXIT_FAILED, EXIT_OK, OneLineParser, add_settings_arguments, check_settings, progress_bar,
                     tracker_settings)

LAYOUT_NAMES = ("otb", "lasot", "got10k", "uav123", "vot")
SUBSET_NAMES = ("otb2013", "otb50", "otb100", "lasot-test")

EPILOG = """\
DATASET_DIR is read as downloaded: OTB-100 (and OTB-2013/50, MIL), LaSOT, GOT-10k, UAV123 or VOT,
detected from the folder or named with --layout.  A sequence that cannot be read is named with its
reason on stderr and the others still run (exit 1).

Writes OUT/<filter>/<Sequence>.txt (one x,y,w,h line per ground-truth line, in that sequence's own
convention: OTB folders 1-based, MIL data 0-based; rows not tracked are 0,0,0,0) with a .json run
record and a .confidence.csv (per-frame confidence and status) beside it, OUT/summary.json,
OUT/summary.md, OUT/toolkit/<layout>/<filter>/ (the results in the layout of the benchmark's own
toolkit: OTB, LaSOT, UAV123 <seq>.txt; GOT-10k <seq>/<seq>_001.txt and <seq>_time.txt, a test-split
submission when zipped), OUT/success.png, OUT/precision.png, OUT/attributes.png (success AUC per OTB
attribute, from DATASET_DIR/attr_list.txt or --attributes) and OUT/report.html (everything in one
self-contained page, with thumbnails of the frames where the best tracker fails).
Existing results of a matching run (same tracker, sequence, seed, frames and effective options) are
reused unless --force.  The tracker options (--config, --model, --detector, --set) apply to every
tracker listed; one a listed tracker does not take is an error naming that tracker.
--compare DIR_A DIR_B prints per tracker and sequence AUC(B) - AUC(A) from the two summary.json.
"""


def build_parser() -> OneLineParser:
    parser = OneLineParser(prog="vidtrack eval", epilog=EPILOG,
                           description="Evaluate trackers on benchmark sequences (OTB, MIL, LaSOT, GOT-10k, UAV123, "
                                       "VOT): OTB success AUC, precision@20, normalised precision, PASCAL score, "
                                       "centre error, GOT-10k's AO, SR0.5 and SR0.75, fps.")
    parser.add_argument("dataset", metavar="DATASET_DIR", nargs="?",
                        help="a benchmark folder as downloaded (OTB, MIL, LaSOT, GOT-10k, UAV123, VOT), "
                             "or one sequence folder")
    parser.add_argument("--filter", metavar="A,B,C", help="comma-separated tracker names (required)")
    parser.add_argument("--compare", nargs=2, metavar=("DIR_A", "DIR_B"),
                        help="instead of evaluating: print the change in AUC from DIR_A to DIR_B (two --out folders)")
    parser.add_argument("--attributes", metavar="FILE",
                        help="OTB attribute file (name<TAB>TAG, TAG, ...; default: DATASET_DIR/attr_list.txt if any)")
    parser.add_argument("--layout", choices=LAYOUT_NAMES,
                        help="the dataset's layout (default: detected from the folder)")
    parser.add_argument("--sequences", metavar="S1,S2|LIST.txt",
                        help="only these sequences, named or listed one a line in a .txt file (default: all)")
    parser.add_argument("--subset", choices=SUBSET_NAMES,
                        help="only the sequences of a published list (those the dataset lacks are reported)")
    parser.add_argument("--out", default="results", metavar="DIR", help="output folder (default: results)")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="run N jobs (tracker x sequence) in parallel processes (default 1)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="send the jobs to this Dask distributed scheduler (e.g. tcp://host:8786)")
    parser.add_argument("--in-process", action="store_true",
                        help="run the jobs one by one in this process instead of a fresh process each "
                             "(quicker start; opencv-mil's results then depend on the job order)")
    parser.add_argument("--force", action="store_true", help="re-run even when a matching result exists")
    parser.add_argument("--seed", type=int, default=0, help="tracker random seed (default 0)")
    parser.add_argument("--max-frames", type=int, metavar="N",
                        help="track at most N frames per sequence (quick checks; scores those frames only)")
    parser.add_argument("--rerun", metavar="DIR", help="also write DIR/<filter>/<Sequence>.rrd Rerun recordings")
    parser.add_argument("--no-plots", action="store_true", help="skip the success and precision plots")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars or messages")
    add_settings_arguments(parser)
    return parser


def _names(text: str, option: str) -> list[str]:
    names = []
    for name in (n.strip() for n in text.split(",")):
        if name and name not in names:
            names.append(name)
    if not names:
        raise UsageError(f"{option} needs at least one name")
    return names


def main(argv: list[str]) -> int:
    """Entry point of ``vidtrack eval`` (exit 0, or 2 on bad input; 1 when a tracker failed)."""
    from ..eval.attributes import by_attribute
    from ..eval.datasets import read_dataset
    from ..eval.evaluation import run_evaluation
    from ..eval.html_report import write_report
    from ..eval.plots import attribute_plot, write_plots
    from ..eval.report import format_attribute_table, format_confidence_table, format_table, write_summary
    from ..eval.results import check_writable_folder
    from ..eval.toolkit import write_toolkit_results
    from ..recipes import registry

    args = build_parser().parse_args(argv)
    if args.compare:
        if args.dataset or args.filter:
            raise UsageError("--compare DIR_A DIR_B takes no DATASET_DIR or --filter")
        return _compare(*args.compare)
    if not args.dataset or not args.filter:
        raise UsageError("DATASET_DIR and --filter are required (or --compare DIR_A DIR_B)")
    filters = _names(args.filter, "--filter")
    recipes = registry()
    unknown = [name for name in filters if name not in recipes]
    if unknown:
        raise UsageError(f"unknown filter {unknown[0]!r}; valid filters: {', '.join(sorted(recipes))}")
    if args.jobs < 1:
        raise UsageError("--jobs must be at least 1")
    if args.in_process and (args.jobs > 1 or args.scheduler):
        raise UsageError("--in-process runs one job at a time: drop --jobs or --scheduler")
    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError("--max-frames must be at least 1")
    settings = tracker_settings(args)
    for name in filters:
        check_settings(name, settings)   # names the tracker that does not take an option
    if args.rerun:
        try:
            from ..sinks import rerun  # noqa: F401  (fail now, not after the first sequence)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.startswith("vidtrack"):
                raise UsageError("--rerun needs vidtrack.sinks.rerun, which is not in this build") from None
            raise UsageError(f"--rerun needs the rerun-sdk package ({exc.name} is missing)") from None
    if args.sequences and args.subset:
        raise UsageError("--sequences and --subset both choose sequences: give one")
    names = _sequence_names(args.sequences) if args.sequences else None
    reading = read_dataset(args.dataset, names, layout=args.layout, subset=args.subset)
    if not reading.sequences:
        raise DatasetError(next(iter(reading.errors.values())))
    if not args.quiet:
        for reason in reading.errors.values():
            print(f"vidtrack eval: skipped: {reason}", file=sys.stderr)
    sequences = reading.sequences
    check_writable_folder(args.out)          # created if missing; unwritable is bad input, found now
    if args.rerun and not args.scheduler:    # (on a cluster the workers write the recordings)
        check_writable_folder(args.rerun)
    attributes = _attributes(args.attributes, args.dataset)

    def report(output) -> None:
        if args.quiet:
            return
        if output.status == "failed":
            print(f"vidtrack eval: {output.filter_name} FAILED on {output.sequence_name}: {output.error}",
                  file=sys.stderr)
        elif output.status == "reused":
            print(f"vidtrack eval: {output.filter_name} {output.sequence_name}: reused the earlier result",
                  file=sys.stderr)

    evaluation = run_evaluation(sequences, filters, args.out, seed=args.seed, max_frames=args.max_frames,
                                settings=settings, force=args.force, workers=args.jobs, scheduler=args.scheduler,
                                isolate=not args.in_process, rerun_dir=args.rerun,
                                progress=None if args.quiet else progress_bar, on_output=report,
                                unreadable=reading.errors)
    per_attribute = by_attribute(evaluation.summary, attributes) if attributes else None
    json_path, md_path = write_summary(args.out, evaluation.summary, per_attribute)
    written = [json_path, md_path, *write_toolkit_results(args.out, sequences, filters, evaluation.records)]
    if not args.no_plots:
        written += write_plots(args.out, evaluation.curves, filters, [s.name for s in sequences])[:2]
        if per_attribute and any(per_attribute.values()):
            written.append(attribute_plot(Path(args.out) / "attributes.png", per_attribute))
    plots = [] if args.no_plots else [Path(args.out) / f for f in ("success.png", "precision.png", "attributes.png")]
    written.append(write_report(args.out, evaluation.summary, sequences, by_attribute=per_attribute, plots=plots))
    print(format_table(evaluation.summary))
    print("\n" + format_confidence_table(evaluation.summary))
    if per_attribute and any(per_attribute.values()):
        print("\n" + format_attribute_table(per_attribute, evaluation.summary))
    if not args.quiet:
        counts = {s: list(evaluation.status.values()).count(s) for s in ("done", "reused", "failed")}
        print(f"vidtrack eval: {counts['done']} run, {counts['reused']} reused, {counts['failed']} failed; "
              f"wrote {', '.join(str(p) for p in written)} and {Path(args.out)}/<filter>/<Sequence>.txt",
              file=sys.stderr)
    if reading.errors:
        print(f"vidtrack eval: {len(reading.errors)} sequence(s) could not be read: "
              + "; ".join(reading.errors.values()), file=sys.stderr)
    failed = "failed" in evaluation.status.values() or bool(reading.errors)
    return EXIT_FAILED if failed else EXIT_OK


def _sequence_names(option: str) -> list[str]:
    """``--sequences``: a list file (one name a line) or comma-separated names."""
    from ..eval.datasets import read_names

    if option.lower().endswith(".txt") or Path(option).is_file():
        if not Path(option).is_file():
            raise UsageError(f"--sequences: no such file: {option}")
        return read_names(option)
    return _names(option, "--sequences")


def _attributes(option: str | None, dataset: str) -> dict[str, tuple[str, ...]] | None:
    """The attribute table from ``--attributes FILE``, else the dataset's ``attr_list.txt``, else None."""
    from ..eval.attributes import find_attribute_file, read_attributes

    if option is not None:
        if not Path(option).is_file():
            raise UsageError(f"--attributes: no such file: {option}")
        return read_attributes(option)
    found = find_attribute_file(dataset)
    return read_attributes(found) if found is not None else None


def _compare(dir_a: str, dir_b: str) -> int:
    from ..eval.compare import compare, format_comparison, read_summary

    a, b = read_summary(dir_a), read_summary(dir_b)
    print(f"AUC change from A = {dir_a} to B = {dir_b} (change = B - A; |change| >= 0.05 marked)")
    print(format_comparison(compare(a, b)))
    return EXIT_OK
