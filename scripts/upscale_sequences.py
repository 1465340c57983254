"""Write a copy of benchmark sequences with frames and ground truth scaled by a factor (default 2x).

Frame size must not change what a tracker does when every parameter is in
units of the box; this makes the check possible::

    python scripts/upscale_sequences.py ../shared/data/sequences /tmp/validate2x \\
        --sequences Couple,Crossing,Dog,Freeman1,Human8,Jogging,Suv
    vidtrack eval /tmp/validate2x --filter nh,pf,bayes,cbt,mil --out /tmp/r2x

The copy goes to a folder outside the repository (benchmark data never enters
the project).  Each sequence is written in the OTB layout (``img/`` +
``groundtruth_rect.txt``, 1-based boxes: the 0-based pixel box of the
loader's ``to_pixels`` scaled about the image origin, plus 1); rows that are
not annotated stay ``0,0,0,0``.  A MIL-layout sequence's run range
(``*_frames.txt``) is not carried over: the copy holds every frame.  ``attr_list.txt`` is copied for the
sequences written, when the dataset has one.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.eval.datasets import annotated_rows, load_dataset  # noqa: E402

#: The copy is in the OTB layout, whose boxes are 1-based.
OTB_ORIGIN = 1


def copy_parser(description: str) -> argparse.ArgumentParser:
    """The arguments every sequence-copying script takes: the dataset, the output folder, ``--sequences``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("dataset", help="folder of sequence folders")
    parser.add_argument("out", help="output folder (outside the repository)")
    parser.add_argument("--sequences", help="comma-separated names (default: all)")
    return parser


def outside_repository(folder: str) -> Path:
    """``folder`` as a path, or exit when it lies inside the repository (benchmark data never enters it)."""
    out = Path(folder)
    if out.resolve().is_relative_to(Path(__file__).resolve().parents[1]):
        raise SystemExit("write the copy outside the repository")
    return out


def copy_attributes(dataset: str | Path, out: Path, sequences) -> None:
    """Copy the lines of ``dataset/attr_list.txt`` (if any) that name one of ``sequences`` to ``out``."""
    attrs = Path(dataset) / "attr_list.txt"
    if attrs.is_file():
        keep = {s.name for s in sequences}
        lines = [line for line in attrs.read_text().splitlines() if line.split("\t")[0].strip() in keep]
        (out / "attr_list.txt").write_text("\n".join(lines) + "\n")


def copy_sequence(sequence, out: Path, image_map, box_map, *, keep=None) -> int:
    """Write ``sequence`` under ``out/<name>`` in the OTB layout, each frame and box mapped; returns the frame count.

    ``image_map(k, image)`` gives frame ``k``'s new image; ``box_map(k, box,
    (width, height))`` the new 0-based pixel ``(x, y, w, h)`` of its annotated
    box (the frame's original size given); rows that are not annotated stay
    ``0,0,0,0``.  ``keep``: the 0-based indices of the frames to copy, in
    order (default all); the copy numbers them from 1 without gaps.
    """
    folder = out / sequence.name / "img"
    folder.mkdir(parents=True, exist_ok=True)
    keep = list(range(len(sequence.files))) if keep is None else [int(k) for k in keep]
    size = None
    for written, k in enumerate(keep):
        path = sequence.files[k]
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise SystemExit(f"cannot read {path}")
        size = (image.shape[1], image.shape[0])
        suffix = Path(path).suffix.lower()
        name = folder / f"{written + 1:05d}{suffix if suffix in ('.png', '.jpg', '.jpeg') else '.png'}"
        params = [cv2.IMWRITE_JPEG_QUALITY, 95] if name.suffix in (".jpg", ".jpeg") else []
        cv2.imwrite(str(name), image_map(k, image), params)
    rows = []
    annotated = annotated_rows(sequence.ground_truth)
    for row in (k for k in keep if k < len(annotated)):
        if not annotated[row]:
            rows.append("0,0,0,0")
            continue
        px = sequence.to_pixels(sequence.ground_truth_box(row))
        x, y, w, h = box_map(row, px.as_array(), size)
        rows.append(f"{x + OTB_ORIGIN:.2f},{y + OTB_ORIGIN:.2f},{w:.2f},{h:.2f}")
    (out / sequence.name / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return len(keep)


def upscale_sequence(sequence, out: Path, factor: float) -> int:
    """Write ``sequence`` scaled by ``factor`` (frames and boxes, about the image origin) under ``out/<name>``."""
    return copy_sequence(
        sequence, out,
        lambda k, image: cv2.resize(image, None, fx=factor, fy=factor, interpolation=cv2.INTER_LINEAR),
        lambda k, box, size: tuple(factor * float(v) for v in box))


def write_copies(args: argparse.Namespace, copy_one) -> int:
    """Copy the sequences :func:`copy_parser`'s ``args`` name to ``args.out``, then their attributes; exit code 0.

    ``copy_one(sequence, out)`` writes one sequence and returns what to print after its name.
    """
    names = args.sequences.split(",") if args.sequences else None
    out = outside_repository(args.out)
    sequences = load_dataset(args.dataset, names)
    for sequence in sequences:
        print(f"{sequence.name}: {copy_one(sequence, out)}")
    copy_attributes(args.dataset, out, sequences)
    return 0


def main(argv=None) -> int:
    parser = copy_parser(__doc__.splitlines()[0])
    parser.add_argument("--factor", type=float, default=2.0, help="scale factor (default 2)")
    args = parser.parse_args(argv)
    return write_copies(args, lambda sequence, out: f"{upscale_sequence(sequence, out, args.factor)} frames "
                                                    f"x{args.factor:g}")


if __name__ == "__main__":
    raise SystemExit(main())
