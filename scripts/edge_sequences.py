"""Write a copy of benchmark sequences in which the target stays at the frame's side.

Trackers that have lost their target often come to rest against the
frame's edge, where benchmark targets seldom are, so a confidence fitted on
benchmark video learns that a box at the edge is a lost one.  A target that
really moves along the edge (a car at the side of a road camera, a person
walking past the frame's border) is then reported lost while it is tracked.
This copy makes that case: each frame is cropped to a window ``fraction``
of the frame's width (its full height) whose left (or right) side follows
the target, so that the target's box starts ``gap`` box widths from it and
stays there, partly out of view when ``gap`` is negative, as a camera
panning with the target would see it.  The side is the one the target's
first box is nearer; where the window would leave the frame it stops at the
frame's side and the target moves away from the window's edge.

The target's box on a frame that is not annotated (the MIL layout
annotates every fifth) is interpolated linearly between its annotated
neighbours for the crop; the copy's annotations are the original boxes
moved into the window and clipped to it, on the same rows::

    python scripts/edge_sequences.py ../shared/data/sequences /tmp/tune-edge \\
        --sequences David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling
    vidtrack eval /tmp/tune-edge --filter mil --out /tmp/r-edge

The copy is in the OTB layout (``img/`` + ``groundtruth_rect.txt``, 1-based
boxes) in a folder outside the repository; a MIL-layout sequence's run range
is not carried over (the copy holds every frame).
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from upscale_sequences import copy_parser, copy_sequence, write_copies  # noqa: E402
from vidtrack.eval.datasets import annotated_rows  # noqa: E402


def interpolated_boxes(boxes: np.ndarray, annotated: np.ndarray) -> np.ndarray:
    """``(N, 4)`` pixel boxes with the rows that are not ``annotated`` interpolated linearly (held at the ends)."""
    boxes = np.asarray(boxes, float)
    known = np.flatnonzero(annotated)
    rows = np.arange(len(boxes))
    return np.stack([np.interp(rows, known, boxes[known, j]) for j in range(4)], axis=1)


def window_origins(boxes: np.ndarray, frame_width: float, window_width: float, gap: float) -> np.ndarray:
    """``(N,)`` left sides of the crop window keeping each box ``gap`` box widths from the window's side.

    The side is the one the first box is nearer (left when its centre is in the frame's left half); the
    window stays inside the frame.
    """
    x, w = boxes[:, 0], boxes[:, 2]
    if x[0] + w[0] / 2.0 < frame_width / 2.0:
        left = x - gap * w
    else:
        left = x + w + gap * w - window_width
    return np.clip(np.round(left), 0.0, frame_width - window_width)


def crop_box(box, left: float, window_width: float) -> tuple[float, float, float, float]:
    """The pixel box ``(x, y, w, h)`` moved into a window starting at ``left``, clipped to its width."""
    x, y, w, h = (float(v) for v in box)
    x0, x1 = max(x - left, 0.0), min(x + w - left, window_width)
    return x0, y, max(x1 - x0, 1.0), h


def edge_sequence(sequence, out: Path, fraction: float, gap: float) -> int:
    """Write ``sequence`` cropped to the window that keeps the target at its side under ``out/<name>``."""
    annotated = np.asarray(annotated_rows(sequence.ground_truth), bool)
    boxes = np.array([sequence.to_pixels(sequence.ground_truth_box(k)).as_array() if annotated[k]
                      else np.zeros(4) for k in range(len(annotated))], float)
    track = interpolated_boxes(boxes, annotated)
    width = sequence.frame_size[0] if sequence.frame_size else cv2.imread(str(sequence.files[0])).shape[1]
    window = int(round(fraction * width))
    lefts = window_origins(track, width, window, gap)
    return copy_sequence(sequence, out,
                         lambda k, image: image[:, int(lefts[k]):int(lefts[k]) + window].copy(),
                         lambda k, box, size: crop_box(box, lefts[k], window))


def main(argv=None) -> int:
    parser = copy_parser(__doc__.splitlines()[0])
    parser.add_argument("--fraction", type=float, default=0.6,
                        help="the window's width as a fraction of the frame's (default 0.6)")
    parser.add_argument("--gap", type=float, default=-0.15,
                        help="the target's box starts this many box widths inside the window's side; "
                             "negative: partly out of view (default -0.15)")
    args = parser.parse_args(argv)
    if not 0.0 < args.fraction <= 1.0 or not -0.5 <= args.gap <= 1.0:
        raise SystemExit("--fraction must be in (0, 1] and --gap in [-0.5, 1]")
    return write_copies(args, lambda sequence, out: f"{edge_sequence(sequence, out, args.fraction, args.gap)} "
                                                    f"frames, a window {args.fraction:g} of the width")


if __name__ == "__main__":
    raise SystemExit(main())
