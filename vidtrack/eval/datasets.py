"""Benchmark sequence loaders: the OTB layout and the original MIL layout.

Layouts
-------
OTB (Wu, Lim, Yang, "Online Object Tracking: A Benchmark", CVPR 2013)::

    Girl/img/0001.jpg ...          frames, sorted by name
    Girl/groundtruth_rect.txt      one x,y,w,h row per frame (comma, tab or space)
    Girl/mil_frames.txt            optional: marks a MIL sequence copied into this layout

MIL (Babenko, Yang, Belongie, "Visual Tracking with Online Multiple Instance
Learning", CVPR 2009)::

    sylv/imgs/img00000.png ...     frames, numbered
    sylv/sylv_gt.txt               one x,y,w,h row per annotated-or-not frame
    sylv/sylv_frames.txt           "start,end": the frame numbers the paper ran on

Coordinate convention (the rule the evaluation applies)
-------------------------------------------------------
Ground truth is kept exactly as published.  A sequence is **0-based** when it
is MIL data (the MIL layout, or any folder holding ``mil_frames.txt`` or a
``*_frames.txt``): MILTrack is C++/OpenCV code and counts pixels from 0.  Any
other OTB-layout folder is **1-based** (OTB's MATLAB convention).  The
trackers work in 0-based pixels, so the init box is shifted by ``-origin`` and
every tracked box by ``+origin`` before it is written to a result file
(:meth:`BenchmarkSequence.to_pixels`, :meth:`BenchmarkSequence.from_pixels`).

Ground-truth rows and frames
----------------------------
Row ``i`` of the ground truth belongs to the ``i``-th image in sorted order.
When a MIL folder holds more images than rows (MIL ``sylv`` has
``img00000``..``img01344`` for 1344 rows, range ``1,1344``), the rows belong to
the images whose number lies in the frames range.  Rows that are all zero, not
finite, or have ``w <= 0`` or ``h <= 0`` are "not annotated" (MIL annotates
every 5th frame) and are skipped by every metric.  The evaluated frames are
those of the MIL frames range (the whole sequence without one), from the
first annotated row inside it, which is also the frame the tracker is
initialised on.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DatasetError, SourceError
from ..sources import IMAGE_SUFFIXES
from ..types import Box, split_numbers

OTB_IMAGES, MIL_IMAGES = "img", "imgs"
OTB_GROUND_TRUTH = "groundtruth_rect.txt"
MIL_FRAMES = "mil_frames.txt"
_NUMBER = re.compile(r"(\d+)")


@dataclass(frozen=True, eq=False)
class BenchmarkSequence:
    """One benchmark sequence: its frames, ground truth and conventions.

    Attributes
    ----------
    name
        The folder name (``Girl``, ``FaceOcc2`` ...).
    path
        The sequence folder.
    files
        Image files, one per ground-truth row, in order.
    ground_truth
        ``(N, 4)`` float array of ``x, y, w, h`` rows in the sequence's own
        convention (read-only).
    origin
        1 for OTB (1-based pixels), 0 for MIL (0-based pixels).
    layout
        ``"otb"`` or ``"mil"`` (the folder layout it was read from).
    run_range
        ``(start, stop)`` row indices (Python slice) of the frames the
        sequence's paper ran on; the whole sequence unless a MIL frames
        file says otherwise.
    """

    name: str
    path: Path
    files: tuple[Path, ...]
    ground_truth: np.ndarray
    origin: int
    layout: str
    run_range: tuple[int, int]

    def __len__(self) -> int:
        return len(self.files)

    @property
    def annotated(self) -> np.ndarray:
        """``(N,)`` bool: rows that carry a real box."""
        return annotated_rows(self.ground_truth)

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


def read_boxes(path: Path) -> np.ndarray:
    """Read a ground-truth or result file (see :func:`parse_boxes`)."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig", errors="replace")  # -sig: a Windows BOM is read
    except OSError as exc:
        raise DatasetError(f"cannot read {path}: {exc.strerror or exc}") from None
    return parse_boxes(text, source=str(path))


def _frame_number(path: Path) -> int | None:
    numbers = _NUMBER.findall(path.stem)
    return int(numbers[-1]) if numbers else None


def _sort_key(path: Path):
    number = _frame_number(path)
    return (number if number is not None else -1, path.name)


def _images(folder: Path) -> list[Path]:
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES),
                  key=_sort_key)


def _image_folder(folder: Path) -> Path | None:
    for name in (OTB_IMAGES, MIL_IMAGES):
        if (folder / name).is_dir():
            return folder / name
    return None


def _mil_file(folder: Path, suffix: str) -> Path | None:
    """``<name>_gt.txt`` / ``<name>_frames.txt``, preferring the folder's own name."""
    own = folder / f"{folder.name}{suffix}"
    if own.is_file():
        return own
    own_lower = folder / f"{folder.name.lower()}{suffix}"
    if own_lower.is_file():
        return own_lower
    candidates = sorted(p for p in folder.glob(f"*{suffix}") if p.is_file())
    return candidates[0] if len(candidates) == 1 else None


def _read_frames_range(path: Path) -> tuple[int, int]:
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    numbers = split_numbers(text)
    try:
        start, end = (int(float(p)) for p in numbers[:2])
    except ValueError:
        raise DatasetError(f"{path}: expected 'start,end' frame numbers") from None
    if end < start:
        raise DatasetError(f"{path}: expected 'start,end' frame numbers with start <= end")
    return start, end


def is_sequence_folder(folder: Path) -> bool:
    """True when ``folder`` has an ``img/`` or ``imgs/`` image folder."""
    return Path(folder).is_dir() and _image_folder(Path(folder)) is not None


def load_sequence(folder: str | Path) -> BenchmarkSequence:
    """Load one sequence folder (OTB or MIL layout).

    Raises
    ------
    DatasetError
        No image folder or no images, no ground truth, a ground truth whose
        row count matches neither the images nor the MIL frames range, or no
        annotated row.
    """
    folder = Path(folder).resolve()  # absolute: jobs may run in other processes or machines
    name = folder.name
    images_dir = _image_folder(folder)
    if images_dir is None:
        raise DatasetError(f"sequence {name}: no img/ or imgs/ folder in {folder}")
    images = _images(images_dir)
    if not images:
        raise DatasetError(f"sequence {name}: {images_dir} holds no images")

    gt_path = folder / OTB_GROUND_TRUTH
    if not gt_path.is_file():
        gt_path = _mil_file(folder, "_gt.txt")
    if gt_path is None:
        raise DatasetError(f"sequence {name}: images but no ground truth "
                           f"({OTB_GROUND_TRUTH} or {name}_gt.txt) in {folder}")
    frames_path = folder / MIL_FRAMES if (folder / MIL_FRAMES).is_file() else _mil_file(folder, "_frames.txt")
    is_mil = frames_path is not None or images_dir.name == MIL_IMAGES
    ground_truth = read_boxes(gt_path)
    ground_truth.setflags(write=False)

    frames_range = _read_frames_range(frames_path) if frames_path is not None else None
    numbers = [_frame_number(p) for p in images]

    def in_range(number: int | None) -> bool:
        return frames_range is not None and number is not None and frames_range[0] <= number <= frames_range[1]

    if len(ground_truth) == len(images):
        files = images
    elif frames_range is not None and len(ground_truth) == sum(map(in_range, numbers)):
        files = [p for p, n in zip(images, numbers) if in_range(n)]
    else:
        raise DatasetError(f"sequence {name}: {gt_path.name} has {len(ground_truth)} rows "
                           f"but {images_dir.name}/ holds {len(images)} images")

    run_range = (0, len(files))
    if frames_range is not None:
        inside = [i for i, p in enumerate(files) if in_range(_frame_number(p))]
        if inside:
            run_range = (inside[0], inside[-1] + 1)
    sequence = BenchmarkSequence(name=name, path=folder, files=tuple(files), ground_truth=ground_truth,
                                 origin=0 if is_mil else 1, layout="mil" if images_dir.name == MIL_IMAGES else "otb",
                                 run_range=run_range)
    check_init_box(sequence, gt_path.name)  # raises DatasetError when nothing is annotated
    return sequence


def check_init_box(sequence: BenchmarkSequence, gt_name: str) -> None:
    """Reject a sequence whose frames differ in size or whose init ground-truth box is not (mostly) inside.

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


def find_sequences(dataset: str | Path) -> list[Path]:
    """Sequence folders of a dataset folder (or the folder itself if it is one), by name.

    Raises
    ------
    DatasetError
        When the path does not exist or holds no sequence.
    """
    dataset = Path(dataset).resolve()
    if not dataset.is_dir():
        raise DatasetError(f"no such dataset folder: {dataset}")
    if is_sequence_folder(dataset):
        return [dataset]
    folders = sorted((p for p in dataset.iterdir() if is_sequence_folder(p)), key=lambda p: p.name.lower())
    if not folders:
        raise DatasetError(f"no sequences in {dataset} (expected sub-folders with img/ or imgs/ "
                           f"and a ground-truth file)")
    return folders


def load_dataset(dataset: str | Path, names: list[str] | None = None) -> list[BenchmarkSequence]:
    """Load the sequences of ``dataset`` (all, or those in ``names``, in that order).

    Raises
    ------
    DatasetError
        For an unknown sequence name (the message lists the valid ones) or a
        malformed sequence (see :func:`load_sequence`).
    """
    folders = {p.name: p for p in find_sequences(dataset)}
    if names is None:
        return [load_sequence(p) for p in folders.values()]
    by_lower = {n.lower(): n for n in folders}
    chosen = []
    for name in names:
        key = name if name in folders else by_lower.get(name.lower())
        if key is None:
            raise DatasetError(f"unknown sequence {name!r}; sequences in {dataset}: {', '.join(folders)}")
        if key not in chosen:
            chosen.append(key)
    return [load_sequence(folders[n]) for n in chosen]
