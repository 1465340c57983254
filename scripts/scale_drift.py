"""The scale filter alone, given the target's true centre: how far its size drifts from the ground truth.

A tracker's size error mixes the scale estimate with the errors of its
centre and of its fusion.  This isolates the estimate: the scale filter of a
tracker's correlation filter (DSST's 1-D filter, Danelljan, Häger, Khan &
Felsberg, "Accurate Scale Estimation for Robust Visual Tracking", BMVC 2014;
:class:`~vidtrack.measure.scale_filter.ScaleFilter`), configured as the
tracker configures it (``--filter``, and any ``--set`` of its options), is
started on the first ground-truth box and then, in every frame, estimates
the scale change at the ground-truth centre (interpolated between annotated
frames) from its own last size, and learns at the box it estimated.  It
learns in every frame, where a tracker learns only from the frames it is
confident of, so the drift measured is the scale filter's own.  It prints,
per sequence, the ratio of its size ``sqrt(w h)`` to the ground truth's on
the annotated frames: at the last one, and the mean and the largest
``|log|`` of the ratio::

    python scripts/scale_drift.py ../shared/data/sequences --sequences Human9,Girl --filter mil
    python scripts/scale_drift.py ../shared/data/sequences --filter nh --set cf.scale_rate=0.01

``--trace DIR`` also writes, per sequence, ``DIR/<sequence>.csv``: for every
frame the filter's size, the ground truth's (blank where not annotated) and
the ratio of their ``sqrt(w h)``, to see when the size drifts::

    python scripts/scale_drift.py ../shared/data/sequences --sequences Human9 --filter mil --trace DIR

Nothing bounds the size here (the trackers clamp it to a range of the first
frame's), so a drift shows in full.  A tracker whose box size does not come
from a scale filter (``mil-paper``, a detector other than ``cf``, a scale
search over several ``scale_factors``) is refused.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.config import parse_setting  # noqa: E402
from vidtrack.errors import UsageError, VidtrackError  # noqa: E402
from vidtrack.eval.datasets import BenchmarkSequence, annotated_rows, load_dataset  # noqa: E402
from vidtrack.measure.correlation import CorrelationConfig, make_scale_filter  # noqa: E402
from vidtrack.measure.scale_filter import ScaleFilter  # noqa: E402
from vidtrack.recipes import recipe_config  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402
from vidtrack.types import Box  # noqa: E402

TUNE = "David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling"


def scale_filter_config(config) -> CorrelationConfig | None:
    """The correlation filter configuration whose scale filter sizes a tracker's box, or None.

    ``mil``'s filter when the fusion takes the size from it (``fusion.size_from="cf"``); the correlation detector's (``cf`` of the score-map trackers,
    ``detections.cf`` of ``cbt``) when ``detector`` is ``cf``; None for anything else, and when the filter
    searches several scales itself (``scale_factors``) or has no scale filter.
    """
    fusion = getattr(config, "fusion", None)
    if fusion is not None:
        candidates = [config.correlation] if fusion.size_from == "cf" else []
    elif getattr(config, "detector", None) == "cf":
        candidates = [getattr(config, "cf", None), getattr(getattr(config, "detections", None), "cf", None)]
    else:
        candidates = []
    for candidate in candidates:
        if (isinstance(candidate, CorrelationConfig) and candidate.scale_filter
                and len(candidate.scale_factors) == 1):
            return candidate
    return None


def tracker_scale_filter(name: str, settings: dict[str, str]) -> ScaleFilter:
    """The scale filter of tracker ``name`` with ``settings`` (``--set`` keys), as its correlation filter builds it.

    Raises
    ------
    UsageError
        For an unknown tracker or setting, and for a tracker whose box size does not come from a scale filter.
    """
    config = recipe_config(name, settings)
    correlation = scale_filter_config(config)
    if correlation is None:
        raise UsageError(f"{name}'s box size does not come from a correlation filter's scale filter "
                         "in this configuration")
    return make_scale_filter(correlation)


def true_centres(truth: np.ndarray) -> np.ndarray:
    """``(N, 2)`` centres of ``(N, 4)`` boxes, interpolated linearly over the rows that are not annotated."""
    valid = annotated_rows(truth)
    rows = np.flatnonzero(valid)
    centres = truth[:, :2] + truth[:, 2:] / 2.0
    frames = np.arange(len(truth))
    return np.stack([np.interp(frames, rows, centres[rows, axis]) for axis in (0, 1)], axis=1)


def follow_sizes(sequence: BenchmarkSequence, scale_filter: ScaleFilter) -> tuple[np.ndarray, np.ndarray]:
    """The scale filter's sizes ``(N, 2)`` on ``sequence``'s run, fed the true centres; and the truth ``(N, 4)``.

    The filter starts on the first ground-truth box; in each later frame it estimates the scale change
    at the true centre from its own last size and learns at the new box.
    """
    start, stop = sequence.eval_range
    truth = np.asarray(sequence.ground_truth[start:stop], float)
    centres = true_centres(truth) - sequence.origin   # the sequence's convention -> 0-based pixels
    source = ImageFolderSource(sequence.path, files=list(sequence.files[start:stop]))
    source.on_skip = lambda message: print(f"scale_drift: {sequence.name}: {message}", file=sys.stderr)
    sizes = []
    for k, frame in enumerate(source):
        if k == 0:
            box = sequence.to_pixels(sequence.ground_truth_box(start))
            scale_filter.initialize(frame.image, box)
            size = np.asarray(box.size, float)
        else:
            size = size * scale_filter.estimate(frame.image, centres[k], size)
            scale_filter.update(frame.image, Box.from_center(*centres[k], *size))
        sizes.append(size)
    return np.array(sizes), truth


def size_ratios(sizes: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``sqrt(w h)`` of ``sizes`` over the ground truth's, on the annotated rows of ``truth``."""
    valid = annotated_rows(truth)
    return np.sqrt(np.prod(sizes[valid], axis=1) / np.prod(truth[valid, 2:], axis=1))


def write_trace(path: Path, sizes: np.ndarray, truth: np.ndarray, ratios: np.ndarray) -> None:
    """Per frame: ``frame, width, height`` of ``sizes``, the ground truth's and the ratio of their ``sqrt(w h)``.

    ``ratios``: :func:`size_ratios` of ``sizes`` and ``truth`` (one per annotated row, in order).  The
    ground truth's cells and the ratio are blank on rows that are not annotated.
    """
    valid = annotated_rows(truth)
    ratios = iter(ratios)
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(["frame", "width", "height", "true_width", "true_height", "ratio"])
        for k, (size, box, annotated) in enumerate(zip(sizes, truth, valid)):
            row = [k, f"{size[0]:.2f}", f"{size[1]:.2f}"]
            row += [f"{box[2]:.2f}", f"{box[3]:.2f}", f"{next(ratios):.4f}"] if annotated else ["", "", ""]
            writer.writerow(row)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="a benchmark folder (any layout vidtrack eval reads)")
    parser.add_argument("--sequences", default=TUNE, help="comma-separated names (default: the tune split)")
    parser.add_argument("--filter", default="mil", help="the tracker whose scale filter runs (default mil)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a setting of the tracker, as vidtrack --set takes it (repeat for several)")
    parser.add_argument("--trace", type=Path, metavar="DIR",
                        help="also write each sequence's sizes per frame to DIR/<sequence>.csv")
    args = parser.parse_args(argv)
    if args.trace is not None:
        try:
            args.trace.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SystemExit(f"scale_drift: --trace {args.trace}: {exc.strerror or exc}") from None
    try:
        settings = dict(parse_setting(item) for item in args.set)
        tracker_scale_filter(args.filter, settings)   # a bad name or setting stops here, before any frame
        sequences = load_dataset(args.dataset, args.sequences.split(","))
        described = " ".join([args.filter, *(f"{k}={v}" for k, v in settings.items())])
        print(f"Scale filter of `{described}` at the true centres: its size sqrt(w h) over the ground truth's\n")
        print("| sequence | frames | annotated | last | mean abs log | largest abs log |")
        print("|---|---:|---:|---:|---:|---:|")
        means = []
        for sequence in sequences:
            sizes, truth = follow_sizes(sequence, tracker_scale_filter(args.filter, settings))
            ratios = size_ratios(sizes, truth)
            if args.trace is not None:
                write_trace(args.trace / f"{sequence.name}.csv", sizes, truth, ratios)
            drift = np.abs(np.log(ratios))
            means.append(float(drift.mean()))
            print(f"| {sequence.name} | {len(sizes)} | {len(ratios)} | {ratios[-1]:.2f} | {drift.mean():.3f} "
                  f"| {drift.max():.3f} |", flush=True)
    except VidtrackError as exc:
        raise SystemExit(f"scale_drift: {exc}") from None
    print(f"| **mean** | | | | {np.mean(means):.3f} | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
