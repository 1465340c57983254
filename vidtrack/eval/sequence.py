"""The benchmark sequence the runner tracks, and the readers every dataset layout shares.

Every layout (:mod:`vidtrack.eval.layouts`) yields a :class:`BenchmarkSequence`:
the image files, one ground-truth row per file in the sequence's own pixel
convention, which rows are annotated, and the frames where the benchmark marks
the target absent or fully occluded.  Rows that are all zero, not finite, or
have ``w <= 0`` or ``h <= 0`` are "not annotated" and skipped by every metric.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import DatasetError, SourceError
from ..sources import IMAGE_SUFFIXES
from ..types import Box, split_numbers

_NUMBER = re.compile(r"(\d+)")


@dataclass(frozen=True, eq=False)
class BenchmarkSequence:
    """One benchmark sequence: its frames, ground truth and conventions.

    Attributes
    ----------
    name
        The sequence name (the folder name, or ``Jogging-1`` for one target
        of a two-target folder).
    path
        The sequence folder.
    files
        Image files, one per ground-truth row, in order.
    ground_truth
        ``(N, 4)`` float array of ``x, y, w, h`` rows in the sequence's own
        convention (read-only; ``NaN`` rows are not annotated: UAV123's rows
        while the target is out of view, LaSOT's frames flagged fully occluded
        or out of view).
    origin
        1 for 1-based pixels (OTB, LaSOT, UAV123), 0 for 0-based (MIL,
        GOT-10k, VOT).
    layout
        The layout it was read from (``otb``, ``mil``, ``lasot``, ``got10k``,
        ``uav123``, ``vot``).
    run_range
        ``(start, stop)`` row indices (Python slice) of the frames the
        sequence's paper ran on; the whole sequence unless a MIL frames
        file says otherwise.
    absent
        ``(N,)`` bool: frames the benchmark marks the target out of view or
        absent (GOT-10k ``absence.label``, LaSOT ``out_of_view.txt``, UAV123
        ``NaN`` rows); None when the layout has no such mark.
    occluded
        ``(N,)`` bool: frames the benchmark marks the target fully occluded
        (LaSOT ``full_occlusion.txt``, GOT-10k ``cover.label`` 0); None when
        the layout has no such mark.
    frame_size
        ``(width, height)`` of the frames, when the reader checked them.
    """

    name: str
    path: Path
    files: tuple[Path, ...]
    ground_truth: np.ndarray
    origin: int
    layout: str
    run_range: tuple[int, int]
    absent: np.ndarray | None = None
    occluded: np.ndarray | None = None
    frame_size: tuple[int, int] | None = None

    def __len__(self) -> int:
        return len(self.files)

    @property
    def annotated(self) -> np.ndarray:
        """``(N,)`` bool: rows that carry a real box."""
        return annotated_rows(self.ground_truth)

    @property
    def present(self) -> np.ndarray:
        """``(N,)`` bool: frames where the target is neither absent nor fully occluded."""
        hidden = np.zeros(len(self), dtype=bool)
        for flags in (self.absent, self.occluded):
            if flags is not None:
                hidden |= flags
        return ~hidden

    @property
    def init_index(self) -> int:
        """Row of the first annotated box inside the run range (the init frame)."""
        start, stop = self.run_range
        rows = np.flatnonzero(self.annotated[start:stop])
        if rows.size == 0:
            raise DatasetError(f"sequence {self.name}: no annotated ground-truth row in its frame range")
        return start + int(rows[0])

    @property
    def eval_range(self) -> tuple[int, int]:
        """``(init_index, stop)``: the rows a full run tracks and every metric scores."""
        return self.init_index, self.run_range[1]

    def to_pixels(self, box: Box) -> Box:
        """A box in the sequence's convention -> 0-based pixels (what trackers use)."""
        return Box(box.x - self.origin, box.y - self.origin, box.w, box.h)

    def from_pixels(self, box: Box) -> Box:
        """A 0-based pixel box -> the sequence's convention (what result files hold)."""
        return Box(box.x + self.origin, box.y + self.origin, box.w, box.h)

    def ground_truth_box(self, row: int) -> Box:
        """Row ``row`` of the ground truth as a :class:`Box` (sequence convention)."""
        return Box.from_array(self.ground_truth[row])


def annotated_rows(boxes: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: rows of an ``(N, 4)`` box array that are real boxes.

    A row is not annotated when it is all zero, not finite, or has ``w <= 0``
    or ``h <= 0`` (the MIL ``0,0,0,0`` rows).
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
    finite = np.all(np.isfinite(boxes), axis=1)
    with np.errstate(invalid="ignore"):
        return finite & (boxes[:, 2] > 0) & (boxes[:, 3] > 0)


def parse_boxes(text: str, *, source: str = "boxes") -> np.ndarray:
    """Rows of ``x,y,w,h`` (separated by commas, tabs or spaces) -> ``(N, 4)`` floats.

    Each row is read by :meth:`Box.parse <vidtrack.types.Box.parse>`, the
    parser of the command line's ``--init-box``.  Blank lines are ignored;
    ``NaN`` values are kept (not annotated); a leading UTF-8 byte-order mark
    and CRLF line ends are accepted.

    Raises
    ------
    DatasetError
        On a row that is not four numbers.
    """
    rows = []
    for number, line in enumerate(text.removeprefix("\ufeff").splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        try:
            box = Box.parse(line)
        except ValueError as exc:
            raise DatasetError(f"{source}, line {number}: {exc}") from None
        rows.append((box.x, box.y, box.w, box.h))
    return np.array(rows, dtype=float).reshape(-1, 4)


def read_text(path: Path) -> str:
    """The text of a dataset file (a Windows byte-order mark is dropped).

    Raises
    ------
    DatasetError
        When the file cannot be read.
    """
    try:
        return Path(path).read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise DatasetError(f"cannot read {path}: {exc.strerror or exc}") from None


def read_boxes(path: Path) -> np.ndarray:
    """Read a ground-truth or result file (see :func:`parse_boxes`)."""
    return parse_boxes(read_text(path), source=str(path))


def read_list(path: Path) -> list[str]:
    """The names of a ``list.txt``, one a line (blank lines and ``#`` comments ignored)."""
    lines = (line.split("#", 1)[0].strip() for line in read_text(path).splitlines())
    return [line for line in lines if line]



def listed_sequences(root: Path, is_sequence, load_sequence) -> dict:
    """``name -> partial(load_sequence, folder)`` for a folder of sequence folders (in ``list.txt`` order
    when there is one) or for one sequence folder (the GOT-10k and VOT layouts)."""
    from functools import partial

    root = Path(root)
    if is_sequence(root):
        return {root.name: partial(load_sequence, root)}
    if (root / "list.txt").is_file():
        names = read_list(root / "list.txt")
    else:
        names = sorted(p.name for p in root.iterdir() if is_sequence(p))
    return {name: partial(load_sequence, root / name) for name in names}

def read_flags(path: Path, count: int) -> np.ndarray:
    """``(count,)`` bool from a file of 0/1 flags (comma- or line-separated), one per frame.

    Raises
    ------
    DatasetError
        When a value is not an integer or the count differs from ``count``.
    """
    values = split_numbers(read_text(path).replace("\n", ","))
    try:
        flags = np.array([int(float(v)) for v in values], dtype=int)
    except ValueError:
        raise DatasetError(f"{path}: expected one integer flag per frame") from None
    if len(flags) != count:
        raise DatasetError(f"{path} has {len(flags)} values for {count} frames")
    return flags


def frame_number(path: Path) -> int | None:
    """The last number in a file's stem (``img00042`` -> 42), or None."""
    numbers = _NUMBER.findall(path.stem)
    return int(numbers[-1]) if numbers else None


def _sort_key(path: Path):
    number = frame_number(path)
    return (number if number is not None else -1, path.name)


def list_images(folder: Path) -> list[Path]:
    """Image files of ``folder``, by frame number (``0001``, ``00001`` and ``img0001`` alike)."""
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES),
                  key=_sort_key)


def require_images(name: str, folder: Path) -> list[Path]:
    """:func:`list_images`, raising :class:`DatasetError` when there are none."""
    if not folder.is_dir():
        raise DatasetError(f"sequence {name}: no image folder {folder}")
    images = list_images(folder)
    if not images:
        raise DatasetError(f"sequence {name}: {folder} holds no images")
    return images


def check_row_count(name: str, ground_truth: np.ndarray, gt_name: str, images: list[Path], folder: Path) -> None:
    """Raise :class:`DatasetError` unless there is one ground-truth row per image."""
    if len(ground_truth) != len(images):
        raise DatasetError(f"sequence {name}: {gt_name} has {len(ground_truth)} rows "
                           f"but {folder.name}/ holds {len(images)} images")


def check_init_box(sequence: BenchmarkSequence, gt_name: str) -> tuple[int, int]:
    """Reject a sequence whose frames differ in size or whose init ground-truth box is not (mostly) inside.

    Returns
    -------
    tuple of int
        The frames' ``(width, height)``.

    Raises
    ------
    DatasetError
        Naming the first odd image, or the ground-truth row, so a bad row is
        not mistaken for a tracker crash.
    """
    from ..sources import check_same_size

    row = sequence.init_index
    box = sequence.to_pixels(sequence.ground_truth_box(row))
    try:
        width, height = check_same_size(list(sequence.files))  # headers only: ~0.1 ms per frame
    except SourceError as exc:
        raise DatasetError(f"sequence {sequence.name}: {exc}") from None
    if not box.is_inside(width, height):
        raise DatasetError(f"sequence {sequence.name}: {gt_name} row {row + 1}: the init box "
                           f"{sequence.ground_truth_box(row)} lies outside the {width}x{height} frame")
    return width, height


def make_sequence(name: str, folder: Path, files: list[Path], ground_truth: np.ndarray, gt_name: str, *,
                  origin: int, layout: str, run_range: tuple[int, int] | None = None,
                  absent: np.ndarray | None = None, occluded: np.ndarray | None = None) -> BenchmarkSequence:
    """A checked, read-only :class:`BenchmarkSequence` (see :func:`check_init_box`)."""
    for array in (ground_truth, absent, occluded):
        if array is not None:
            array.setflags(write=False)
    sequence = BenchmarkSequence(name=name, path=folder.resolve(), files=tuple(files), ground_truth=ground_truth,
                                 origin=origin, layout=layout, run_range=run_range or (0, len(files)),
                                 absent=absent, occluded=occluded)
    return replace(sequence, frame_size=check_init_box(sequence, gt_name))
