"""GOT-10k (Huang, Zhao, Huang, "GOT-10k: A Large High-Diversity Benchmark for Generic Object Tracking
in the Wild", TPAMI 2021).

::

    val/list.txt                               the sequence names, one a line
    val/GOT-10k_Val_000001/00000001.jpg ...    frames, in the sequence folder itself
    val/GOT-10k_Val_000001/groundtruth.txt     one x,y,w,h row per frame (commas), 0-based
    val/GOT-10k_Val_000001/absence.label       one 0/1 a line: 1 = target absent
    val/GOT-10k_Val_000001/cover.label         one 0..8 a line: visible fraction, 0 = fully occluded
    val/GOT-10k_Val_000001/meta_info.ini       ignored

The test split ships only the first box: its later rows are not annotated
(the benchmark's server scores test results).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from ...errors import DatasetError
from ..sequence import (listed_sequences, BenchmarkSequence, check_row_count, make_sequence, read_boxes, read_flags, require_images)

GROUND_TRUTH = "groundtruth.txt"
MARKERS = ("absence.label", "cover.label", "meta_info.ini")


def is_sequence(folder: Path) -> bool:
    """True for a folder with ``groundtruth.txt`` and a GOT-10k label file or a ``GOT-10k_`` name."""
    folder = Path(folder)
    return (folder / GROUND_TRUTH).is_file() and (folder.name.startswith("GOT-10k_")
                                                  or any((folder / m).is_file() for m in MARKERS))


def is_dataset(folder: Path) -> bool:
    """True for a split folder holding GOT-10k sequences."""
    return any(is_sequence(p) for p in Path(folder).iterdir() if p.is_dir())


def dataset_entries(root: Path) -> dict[str, partial]:
    """The sequences of a split folder (in ``list.txt`` order when there is one), or of one sequence folder."""
    return listed_sequences(root, is_sequence, load_sequence)


def load_sequence(folder: Path) -> BenchmarkSequence:
    """Read one GOT-10k sequence folder.

    Raises
    ------
    DatasetError
        Missing folder, images or ground truth, a row count that is neither
        the image count nor one (the test split), a label file of another
        length, or no annotated row.
    """
    folder = Path(folder).resolve()
    name = folder.name
    if not folder.is_dir():
        raise DatasetError(f"sequence {name}: no such folder {folder}")
    images = require_images(name, folder)
    if not (folder / GROUND_TRUTH).is_file():
        raise DatasetError(f"sequence {name}: no {GROUND_TRUTH} in {folder}")
    boxes = read_boxes(folder / GROUND_TRUTH)
    if len(boxes) == 1 and len(images) > 1:  # the test split: the first box only
        boxes = np.vstack([boxes, np.full((len(images) - 1, 4), np.nan)])
    check_row_count(name, boxes, GROUND_TRUTH, images, folder)
    absent = occluded = None
    if (folder / "absence.label").is_file():
        absent = read_flags(folder / "absence.label", len(images)) > 0
    if (folder / "cover.label").is_file():
        occluded = read_flags(folder / "cover.label", len(images)) == 0
    return make_sequence(name, folder, images, boxes, GROUND_TRUTH, origin=0, layout="got10k",
                         absent=absent, occluded=occluded)
