"""LaSOT (Fan et al., "LaSOT: A High-quality Benchmark for Large-scale Single Object Tracking", CVPR 2019).

::

    airplane/airplane-1/img/00000001.jpg ...   frames
    airplane/airplane-1/groundtruth.txt        one x,y,w,h row per frame (commas), 1-based
    airplane/airplane-1/full_occlusion.txt     one 0/1 flag per frame (comma-separated)
    airplane/airplane-1/out_of_view.txt        one 0/1 flag per frame
    airplane/airplane-1/nlp.txt                ignored

The dataset folder may be the LaSOT root (class folders), one class folder,
or one sequence folder.  A frame flagged in ``full_occlusion.txt`` or
``out_of_view.txt`` is not scored: its ground-truth row is read as not
annotated (``NaN``), as LaSOT's toolkit removes those frames before it scores
a sequence (its ``calc_seq_err_robust``; the toolkit still divides by every
frame of the sequence, see docs/evaluation.md).
"""

from __future__ import annotations

import re
from functools import partial
from pathlib import Path

import numpy as np

from ..sequence import BenchmarkSequence, check_row_count, make_sequence, read_boxes, read_flags, require_images

GROUND_TRUTH = "groundtruth.txt"
_NAME = re.compile(r"^(.+)-(\d+)$")


def is_sequence(folder: Path) -> bool:
    """True for ``<class>-<n>/`` holding ``img/`` and ``groundtruth.txt``."""
    folder = Path(folder)
    return (_NAME.match(folder.name) is not None and (folder / "img").is_dir()
            and (folder / GROUND_TRUTH).is_file())


def _class_folder(folder: Path) -> bool:
    return folder.is_dir() and any(is_sequence(p) for p in folder.iterdir() if p.is_dir())


def is_dataset(folder: Path) -> bool:
    """True for a class folder or a folder of class folders."""
    folder = Path(folder)
    return _class_folder(folder) or any(_class_folder(p) for p in folder.iterdir() if p.is_dir())


def dataset_entries(root: Path) -> dict[str, partial]:
    """Every sequence under ``root`` (root, class folder or sequence folder), by name."""
    root = Path(root)
    if is_sequence(root):
        return {root.name: partial(load_sequence, root)}
    classes = [root] if _class_folder(root) else sorted(p for p in root.iterdir() if _class_folder(p))
    found = {}
    for folder in classes:
        sequences = [p for p in folder.iterdir() if is_sequence(p)]
        for path in sorted(sequences, key=lambda p: (_NAME.match(p.name).group(1), int(_NAME.match(p.name).group(2)))):
            found[path.name] = partial(load_sequence, path)
    return found


def load_sequence(folder: Path) -> BenchmarkSequence:
    """Read one LaSOT sequence folder.

    Raises
    ------
    DatasetError
        Missing images or ground truth, a row count that is not the image
        count, a flag file of another length, or no annotated row.
    """
    folder = Path(folder).resolve()
    name = folder.name
    images = require_images(name, folder / "img")
    boxes = read_boxes(folder / GROUND_TRUTH)
    check_row_count(name, boxes, GROUND_TRUTH, images, folder / "img")
    flags = {}
    for key, file in (("occluded", "full_occlusion.txt"), ("absent", "out_of_view.txt")):
        path = folder / file
        flags[key] = read_flags(path, len(images)) > 0 if path.is_file() else None
    hidden = np.zeros(len(images), dtype=bool)
    for marked in flags.values():
        if marked is not None:
            hidden |= marked
    boxes[hidden] = np.nan  # the target is not visible: no metric scores the frame
    return make_sequence(name, folder, images, boxes, GROUND_TRUTH, origin=1, layout="lasot", **flags)
