"""The scale filter alone, given the target's true centre: how far its size drifts from the ground truth.

A tracker's size error mixes the scale estimate with the errors of its
centre and of its fusion.  This isolates the estimate: the scale filter of a
tracker's correlation filter (DSST's 1-D filter, Danelljan, Häger, Khan &
Felsberg, "Accurate Scale Estimation for Robust Visual Tracking", BMVC 2014;
:class:`~vidtrack.measure.scale_filter.ScaleFilter`), configured as the
tracker configures it (``--filter``, and any ``--set`` of its options), is
started on the first ground-truth box and then, every frame, estimates the
scale change at the ground-truth centre (interpolated between annotated
frames) from its own last size, and learns there, as the tracker's filter
learns from its posterior box.  It prints, per sequence, the ratio of its
size ``sqrt(w h)`` to the ground truth's, on annotated frames: at the last
one, and the mean and the largest ``|log|`` of the ratio::

    python scripts/scale_drift.py ../shared/data/sequences --sequences Human9,Girl --filter mil
    python scripts/scale_drift.py ../shared/data/sequences --filter nh --set cf.scale_rate=0.01

Nothing bounds the size here (the trackers clamp it to a range of the first
frame's), so a drift shows in full.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.errors import VidtrackError  # noqa: E402
from vidtrack.eval.datasets import annotated_rows, load_dataset  # noqa: E402
from vidtrack.measure.correlation import CorrelationConfig, make_scale_filter  # noqa: E402
from vidtrack.measure.scale_filter import ScaleFilter  # noqa: E402
from vidtrack.recipes import recipe_config  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402
from vidtrack.types import Box  # noqa: E402

TUNE = "David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling"


def tracker_scale_filter(name: str, settings: dict[str, str]) -> ScaleFilter:
    """The scale filter of tracker ``name`` with ``settings`` (``--set`` keys), as its correlation filter builds it.

    Raises
    ------
    UsageError
        For an unknown tracker or setting.
    ValueError
        When the tracker has no correlation filter, or its scale filter is off.
    """
    config = recipe_config(name, settings)
    correlation = next((getattr(config, field) for field in getattr(config, "__dataclass_fields__", ())
                        if isinstance(getattr(config, field), CorrelationConfig)), None)
    if correlation is None:
        raise ValueError(f"{name} has no correlation filter, hence no scale filter")
    scale_filter = make_scale_filter(correlation)
    if scale_filter is None:
        raise ValueError(f"{name}'s scale filter is off in this configuration")
    return scale_filter


def true_centres(truth: np.ndarray) -> np.ndarray:
    """``(N, 2)`` centres of ``(N, 4)`` boxes, interpolated linearly over the rows that are not annotated."""
    valid = annotated_rows(truth)
    rows = np.flatnonzero(valid)
    centres = truth[:, :2] + truth[:, 2:] / 2.0
    frames = np.arange(len(truth))
    return np.stack([np.interp(frames, rows, centres[rows, axis]) for axis in (0, 1)], axis=1)


def follow_sizes(sequence, scale_filter: ScaleFilter) -> tuple[np.ndarray, np.ndarray]:
    """The scale filter's sizes ``(N, 2)`` on ``sequence``'s run, fed the true centres; and the truth ``(N, 4)``.

    The filter starts on the first ground-truth box; in each later frame it estimates the scale change
    at the true centre from its own last size and learns at the new box.
    """
    start, stop = sequence.eval_range
    truth = np.asarray(sequence.ground_truth[start:stop], float)
    centres = true_centres(truth) - sequence.origin   # the sequence's convention -> 0-based pixels
    source = ImageFolderSource(sequence.path, files=list(sequence.files[start:stop]))
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--sequences", default=TUNE)
    parser.add_argument("--filter", default="mil", help="the tracker whose scale filter runs (default mil)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a setting of the tracker, as vidtrack --set takes it (repeat for several)")
    args = parser.parse_args(argv)
    try:
        settings = dict(item.split("=", 1) for item in args.set)
    except ValueError:
        parser.error("--set takes KEY=VALUE")
    try:
        tracker_scale_filter(args.filter, settings)   # a bad name or setting stops here, before any frame
        sequences = load_dataset(args.dataset, args.sequences.split(","))
    except (VidtrackError, ValueError) as exc:
        raise SystemExit(f"scale_drift: {exc}") from None
    described = " ".join([args.filter, *args.set])
    print(f"Scale filter of `{described}` at the true centres: its size sqrt(w h) over the ground truth's\n")
    print("| sequence | frames | last | mean abs log | largest abs log |")
    print("|---|---:|---:|---:|---:|")
    means = []
    for sequence in sequences:
        sizes, truth = follow_sizes(sequence, tracker_scale_filter(args.filter, settings))
        ratios = size_ratios(sizes, truth)
        drift = np.abs(np.log(ratios))
        means.append(float(drift.mean()))
        print(f"| {sequence.name} | {len(sizes)} | {ratios[-1]:.2f} | {drift.mean():.3f} | {drift.max():.3f} |",
              flush=True)
    print(f"| **mean** | | | {np.mean(means):.3f} | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
