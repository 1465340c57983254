"""Where an evaluation run lost its target, and whether the tracker's confidence and status said so.

``vidtrack eval`` pools the frames whose box misses the target (``IoU = 0``)
into one figure per tracker, the missed loss.  This splits them into spans
of consecutive scored frames, per sequence, with the tracker's mean
confidence over each span and the fraction of its frames marked ``lost``
(:func:`vidtrack.eval.confidence.failure_spans`).  A span at low confidence
but rarely ``lost`` is a failure the confidence saw and the ``lost`` rule did
not act on; one at high confidence is a failure neither saw::

    vidtrack eval ../shared/data/sequences --sequences David,Human9 --filter mil --out RUN
    python scripts/failure_spans.py RUN ../shared/data/sequences
    python scripts/failure_spans.py RUN ../shared/data/sequences --filter mil --min-frames 5

The frames scored are those ``vidtrack eval`` scores for its confidence
table: the annotated ground-truth rows the run tracked, the init frame left
out.  Rows are 0-based ground-truth rows.  A run folder without a tracker's
per-frame confidence files, or a sequence the dataset does not have, stops
the script with one line on stderr.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.errors import DatasetError, VidtrackError  # noqa: E402
from vidtrack.eval import confidence as conf  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402
from vidtrack.eval.results import read_record, result_paths, run_sequences  # noqa: E402
from vidtrack.eval.scoring import score_result  # noqa: E402


def sequence_spans(sequence, run: Path, name: str) -> tuple[list[dict[str, float]], int]:
    """The failure spans of tracker ``name``'s result on ``sequence`` in ``run``, and the number of frames scored.

    The frames are those :func:`~vidtrack.eval.scoring.score_result` scores for the confidence metrics.
    """
    scored = score_result(sequence, result_paths(run, name, sequence.name)[0], read_record(run, name, sequence.name))
    if scored.frames is None:
        raise DatasetError(f"{run / name}: no per-frame confidence file for {sequence.name}")
    return conf.failure_spans(scored.rows, *scored.frames[:3]), len(scored.rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a vidtrack eval output folder (--out)")
    parser.add_argument("dataset", help="the benchmark folder the run was made on")
    parser.add_argument("--filter", help="comma-separated trackers (default: every one in the run)")
    parser.add_argument("--min-frames", type=int, default=3,
                        help="list spans of at least this many scored frames (default 3; all count in the totals)")
    args = parser.parse_args(argv)
    try:
        found = run_sequences(args.run, conf.SUFFIX, "per-frame confidence files",
                              args.filter.split(",") if args.filter else None)
        for name, names in found.items():
            print(f"## `{name}`\n")
            print("| sequence | rows | frames | mean confidence | marked lost |")
            print("|---|---|---:|---:|---:|")
            total = missed = seen = 0
            for sequence in load_dataset(args.dataset, names):
                spans, scored = sequence_spans(sequence, args.run, name)
                total += scored
                for span in spans:
                    missed += span["frames"]
                    seen += span["frames"] if span["confidence"] < 0.5 else 0
                    if span["frames"] >= args.min_frames:
                        print(f"| {sequence.name} | {span['first']}-{span['last']} | {span['frames']} "
                              f"| {span['confidence']:.2f} | {span['lost']:.2f} |")
            share = seen / missed if missed else float("nan")
            print(f"\n{missed} of {total} scored frames miss the target; {share:.2f} of them in spans of mean "
                  "confidence below 0.5.\n")
    except VidtrackError as exc:
        raise SystemExit(f"failure_spans: {exc}") from None
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
