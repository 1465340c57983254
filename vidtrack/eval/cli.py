"""``vidtrack eval DATASET_DIR --filter a,b,c``: run trackers on benchmark sequences and score them."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import UsageError

EPILOG = """\
Writes OUT/<filter>/<Sequence>.txt (one x,y,w,h line per ground-truth line, in that sequence's own
convention: OTB folders 1-based, MIL data 0-based; rows not tracked are 0,0,0,0) with a .json run
record beside it, OUT/summary.json, OUT/summary.md, OUT/success.png and OUT/precision.png.
Existing results of a matching run are reused unless --force.
"""


def build_parser():
    from ..cli import OneLineParser

    parser = OneLineParser(prog="vidtrack eval", epilog=EPILOG,
                           description="Evaluate trackers on benchmark sequences (OTB or MIL layout): "
                                       "OTB success AUC, precision@20, PASCAL score, centre error, fps.")
    parser.add_argument("dataset", metavar="DATASET_DIR",
                        help="folder of sequence folders (img/ + groundtruth_rect.txt, or MIL imgs/ + "
                             "<name>_gt.txt), or one sequence folder")
    parser.add_argument("--filter", required=True, metavar="A,B,C", help="comma-separated tracker names")
    parser.add_argument("--sequences", metavar="S1,S2", help="only these sequences (default: all)")
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
    from ..tracker import registry
    from .datasets import load_dataset
    from .experiment import run_evaluation
    from .plots import write_plots
    from .report import format_table, write_summary

    args = build_parser().parse_args(argv)
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
    if args.rerun:
        try:
            from ..sinks import rerun  # noqa: F401  (fail now, not after the first sequence)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.startswith("vidtrack"):
                raise UsageError("--rerun needs vidtrack.sinks.rerun, which is not in this build") from None
            raise UsageError(f"--rerun needs the rerun-sdk package ({exc.name} is missing)") from None
    names = _names(args.sequences, "--sequences") if args.sequences else None
    sequences = load_dataset(args.dataset, names)

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
                                force=args.force, workers=args.jobs, scheduler=args.scheduler,
                                isolate=not args.in_process,
                                rerun_dir=args.rerun, quiet=args.quiet, on_output=report)
    json_path, md_path = write_summary(args.out, evaluation.summary)
    written = [json_path, md_path]
    if not args.no_plots:
        written += write_plots(args.out, evaluation.curves, filters, [s.name for s in sequences])[:2]
    print(format_table(evaluation.summary))
    if not args.quiet:
        counts = {s: list(evaluation.status.values()).count(s) for s in ("done", "reused", "failed")}
        print(f"vidtrack eval: {counts['done']} run, {counts['reused']} reused, {counts['failed']} failed; "
              f"wrote {', '.join(str(p) for p in written)} and {Path(args.out)}/<filter>/<Sequence>.txt",
              file=sys.stderr)
    return 1 if "failed" in evaluation.status.values() else 0
