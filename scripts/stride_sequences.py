"""Write a copy of benchmark sequences that keeps every ``stride``-th frame: the same video, faster motion.

Fast motion and the motion blur that comes with it are where trackers lose
most on video they have not seen, and the tune split has few sequences of
it.  Keeping frames ``0, s, 2 s, ...`` of a sequence multiplies every
displacement between consecutive frames by ``s`` while the appearance of
each frame stays what it was, so a tracker's search range and motion model
meet fast motion on the same targets::

    python scripts/stride_sequences.py ../shared/data/sequences /tmp/tune-fast2 --stride 2 \\
        --sequences David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling
    vidtrack eval /tmp/tune-fast2 --filter mil --out /tmp/r-fast2

The kept frames' annotations come along (a MIL-layout sequence annotated
every 5th frame keeps the annotated frames among those kept, every 10th
for a stride of 2); the copy is in the OTB layout (``img/`` +
``groundtruth_rect.txt``, 1-based boxes) in a folder outside the
repository.  The first frame is always kept, with its box, so a run starts
from the same box as on the original.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from upscale_sequences import copy_parser, copy_sequence, write_copies  # noqa: E402


def stride_sequence(sequence, out: Path, stride: int) -> int:
    """Write every ``stride``-th frame of ``sequence`` (from the first) under ``out/<name>``; the frame count."""
    keep = range(0, len(sequence.files), stride)
    return copy_sequence(sequence, out, lambda k, image: image, lambda k, box, size: tuple(box), keep=keep)


def main(argv=None) -> int:
    parser = copy_parser(__doc__.splitlines()[0])
    parser.add_argument("--stride", type=int, default=2, help="keep every this many frames (default 2)")
    args = parser.parse_args(argv)
    if args.stride < 1:
        raise SystemExit("--stride must be a positive whole number")
    return write_copies(args, lambda sequence, out: f"{stride_sequence(sequence, out, args.stride)} of "
                                                    f"{len(sequence.files)} frames (every {args.stride})")


if __name__ == "__main__":
    raise SystemExit(main())
