"""VOT (Kristan et al., the Visual Object Tracking challenges) sequence folders.

::

    list.txt                       the sequence names, one a line
    ball/color/00000001.jpg ...    frames (VOT2014 and later); older sets hold them in ball/ itself
    ball/groundtruth.txt           per frame x,y,w,h or a polygon x1,y1,...,xn,yn, 0-based
    ball/sequence                  metadata, ignored

Polygons are reduced to their bounding rectangle (the smallest axis-aligned
box holding every corner), so the scores are those of axis-aligned boxes, not
VOT's polygon overlaps.  Segmentation masks (VOT2020 and later, rows starting
with ``m``) are not read.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from ...errors import DatasetError
from ...types import split_numbers
from ..sequence import (listed_sequences, BenchmarkSequence, check_row_count, list_images, make_sequence, read_text,
                        require_images)

GROUND_TRUTH = "groundtruth.txt"


def is_sequence(folder: Path) -> bool:
    """True for a folder with ``groundtruth.txt`` and ``color/``, a ``sequence`` file or images."""
    folder = Path(folder)
    if not folder.is_dir() or not (folder / GROUND_TRUTH).is_file():
        return False
    return (folder / "color").is_dir() or (folder / "sequence").is_file() or bool(list_images(folder))


def is_dataset(folder: Path) -> bool:
    """True for a folder of VOT sequences."""
    return any(is_sequence(p) for p in Path(folder).iterdir() if p.is_dir())


def region_to_box(values: list[float]) -> tuple[float, float, float, float]:
    """A VOT region (``x,y,w,h`` or a polygon ``x1,y1,...,xn,yn``) -> its bounding ``x, y, w, h``.

    Raises
    ------
    ValueError
        When the values are neither four numbers nor an even count of at least six.
    """
    if len(values) == 4:
        return tuple(values)
    if len(values) < 6 or len(values) % 2:
        raise ValueError(f"expected 4 numbers or a polygon of at least 3 corners, got {len(values)} numbers")
    xs, ys = np.asarray(values[0::2]), np.asarray(values[1::2])
    return float(xs.min()), float(ys.min()), float(xs.max() - xs.min()), float(ys.max() - ys.min())


def parse_regions(text: str, *, source: str) -> np.ndarray:
    """Rows of VOT regions -> ``(N, 4)`` bounding rectangles (see :func:`region_to_box`).

    Raises
    ------
    DatasetError
        On a mask row or a row that is not a rectangle or polygon.
    """
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        if line.startswith("m"):
            raise DatasetError(f"{source}, line {number}: segmentation masks are not supported")
        try:
            rows.append(region_to_box([float(v) for v in split_numbers(line)]))
        except ValueError as exc:
            raise DatasetError(f"{source}, line {number}: {exc}") from None
    return np.array(rows, dtype=float).reshape(-1, 4)


def dataset_entries(root: Path) -> dict[str, partial]:
    """The sequences of a VOT folder (in ``list.txt`` order when there is one), or of one sequence folder."""
    return listed_sequences(root, is_sequence, load_sequence)


def load_sequence(folder: Path) -> BenchmarkSequence:
    """Read one VOT sequence folder.

    Raises
    ------
    DatasetError
        Missing folder, images or ground truth, a row that is not a region,
        a row count that is not the image count, or no annotated row.
    """
    folder = Path(folder).resolve()
    name = folder.name
    if not folder.is_dir():
        raise DatasetError(f"sequence {name}: no such folder {folder}")
    image_folder = folder / "color" if (folder / "color").is_dir() else folder
    images = require_images(name, image_folder)
    if not (folder / GROUND_TRUTH).is_file():
        raise DatasetError(f"sequence {name}: no {GROUND_TRUTH} in {folder}")
    boxes = parse_regions(read_text(folder / GROUND_TRUTH), source=str(folder / GROUND_TRUTH))
    check_row_count(name, boxes, GROUND_TRUTH, images, image_folder)
    return make_sequence(name, folder, images, boxes, GROUND_TRUTH, origin=0, layout="vot")
