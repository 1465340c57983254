"""Write a copy of benchmark sequences under a known, smoothly varying camera zoom.

A tracker's size estimate can only be tuned on sequences whose ground truth
annotates size.  The MIL sequences' boxes keep one size for the whole
sequence whatever the target does, and few of the others change scale much;
this adds a scale change whose truth is exact.  Frame ``t`` (0-based) is
zoomed about the image centre ``C`` by::

    z(t) = 1 - depth (1 - cos(2 pi t / period)) / 2

(``z = 1`` on the first frame, ``1 - depth`` half a period later), each
pixel ``p`` moving to ``C + z (p - C)``; the border beyond the shrunk frame
repeats its edge (``cv2.BORDER_REPLICATE``).  Every annotated box is
transformed the same way; rows that are not annotated stay ``0,0,0,0``::

    python scripts/zoom_sequences.py ../shared/data/sequences /tmp/tune-zoom \\
        --sequences David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling
    vidtrack eval /tmp/tune-zoom --filter mil --out /tmp/r-zoom

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

def zoom_factor(t: int, depth: float, period: float) -> float:
    """``z(t) = 1 - depth (1 - cos(2 pi t / period)) / 2``."""
    return 1.0 - depth * (1.0 - np.cos(2.0 * np.pi * t / period)) / 2.0


def zoom_image(image: np.ndarray, z: float) -> np.ndarray:
    """``image`` zoomed by ``z`` about its centre (bilinear), same size, the border repeating the edge."""
    h, w = image.shape[:2]
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    matrix = np.array([[z, 0.0, cx * (1.0 - z)], [0.0, z, cy * (1.0 - z)]], np.float64)
    return cv2.warpAffine(image, matrix, (w, h), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)


def zoom_box(box, z: float, width: int, height: int) -> tuple[float, float, float, float]:
    """A 0-based pixel box ``(x, y, w, h)`` under :func:`zoom_image`'s map."""
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    x, y, w, h = (float(v) for v in box)
    return cx + z * (x - cx), cy + z * (y - cy), z * w, z * h


def zoom_sequence(sequence, out: Path, depth: float, period: float) -> int:
    """Write ``sequence`` under the zoom under ``out/<name>``; returns the number of frames."""
    return copy_sequence(sequence, out, lambda k, image: zoom_image(image, zoom_factor(k, depth, period)),
                         lambda k, box, size: zoom_box(box, zoom_factor(k, depth, period), *size))


def main(argv=None) -> int:
    parser = copy_parser(__doc__.splitlines()[0])
    parser.add_argument("--depth", type=float, default=0.4, help="largest shrink, 1 - min z (default 0.4)")
    parser.add_argument("--period", type=float, default=200.0, help="frames of one zoom cycle (default 200)")
    args = parser.parse_args(argv)
    if not 0.0 <= args.depth < 1.0 or args.period <= 0:
        raise SystemExit("--depth must be in [0, 1) and --period positive")
    return write_copies(args, lambda sequence, out: f"{zoom_sequence(sequence, out, args.depth, args.period)} "
                                                    f"frames, zoom 1 .. {1 - args.depth:g} every {args.period:g} frames")


if __name__ == "__main__":
    raise SystemExit(main())
