"""UAV123 (Mueller, Smith, Ghanem, "A Benchmark and Simulator for UAV Tracking", ECCV 2016).

::

    Dataset_UAV123/UAV123/data_seq/UAV123/bike1/000001.jpg ...   frames
    Dataset_UAV123/UAV123/anno/UAV123/bike1.txt                  one x,y,w,h row per frame, 1-based;
                                                                 NaN,NaN,NaN,NaN while out of view
    Dataset_UAV123/UAV123/anno/UAV20L/...                        the long-term subset, same layout

The dataset folder is the one holding ``anno/`` and ``data_seq/`` (or its
parent); the subset is ``UAV123`` when present, else the only one there.
A sequence is an annotation file whose name is a frame folder, or one of the
split sequences (``bird1_1``, ``bird1_2`` ...): consecutive frame ranges of one
folder, from :data:`SPLIT_SEQUENCES` (the benchmark's configuration).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from ...errors import DatasetError
from ..sequence import BenchmarkSequence, check_row_count, frame_number, make_sequence, read_boxes, require_images


_SPLIT = """
    bird1 1-253 775-1477 1573-2437
    car1 1-751 751-1627 1627-2629
    car6 1-487 487-1807 1807-2953 2953-3925 3925-4861
    car8 1-1357 1357-2575
    car16 1-415 415-1993
    group1 1-1333 1333-2515 2515-3925 3925-4873
    group2 1-907 907-1771 1771-2683
    group3 1-1567 1567-2827 2827-4369 4369-5527
    person2 1-1189 1189-2623
    person4 1-1501 1501-2743
    person5 1-877 877-2101
    person7 1-1249 1249-2065
    person8 1-1075 1075-1525
    person12 1-601 601-1621
    person14 1-847 847-1813 1813-2923
    person17 1-1501 1501-2347
    person19 1-1243 1243-2791 2791-4357
    truck4 1-577 577-1261
    uav1 1-1555 1555-2377 2473-3469
"""

#: Split sequences: ``name -> (folder, first frame, last frame)`` (``bird1_2`` -> ``("bird1", 775, 1477)``).
SPLIT_SEQUENCES: dict[str, tuple[str, int, int]] = {
    f"{line.split()[0]}_{k}": (line.split()[0], *(int(v) for v in part.split("-")))
    for line in _SPLIT.strip().splitlines() for k, part in enumerate(line.split()[1:], start=1)
}


def _root(folder: Path) -> Path | None:
    folder = Path(folder)
    for candidate in (folder, folder / "UAV123"):
        if (candidate / "anno").is_dir() and (candidate / "data_seq").is_dir():
            return candidate
    return None


def is_sequence(folder: Path) -> bool:
    """UAV123 sequences are not folders of their own (frames and annotation live apart)."""
    return False


def is_dataset(folder: Path) -> bool:
    """True for the folder holding ``anno/`` and ``data_seq/`` (or its parent)."""
    return _root(folder) is not None


def _subset(root: Path) -> str:
    subsets = sorted(p.name for p in (root / "anno").iterdir() if p.is_dir())
    if "UAV123" in subsets or not subsets:
        return "UAV123"
    return subsets[0]


def dataset_entries(root: Path) -> dict[str, partial]:
    """Every annotation file of the subset, by name."""
    base = _root(root)
    if base is None:
        raise DatasetError(f"no anno/ and data_seq/ folders in {root}")
    subset = _subset(base)
    anno = base / "anno" / subset
    names = sorted(p.stem for p in anno.glob("*.txt") if p.is_file())
    found = {}
    for name in names:
        folder, *frames = SPLIT_SEQUENCES.get(name, (name, None, None))
        found[name] = partial(load_sequence, base / "data_seq" / subset / folder, anno / f"{name}.txt",
                              frames_range=None if frames[0] is None else tuple(frames))
    return found


def load_sequence(frames: Path, annotation: Path, *, frames_range: tuple[int, int] | None = None
                  ) -> BenchmarkSequence:
    """Read one UAV123 sequence from its frame folder and annotation file.

    ``frames_range``: the first and last frame number of a split sequence.

    Raises
    ------
    DatasetError
        No frame folder or no images, a row count that is not the image
        count, or no annotated row.
    """
    frames, name = Path(frames).resolve(), Path(annotation).stem
    if not frames.is_dir():
        raise DatasetError(f"sequence {name}: no frame folder {frames}")
    images = require_images(name, frames)
    if frames_range is not None:
        first, last = frames_range
        images = [p for p in images if (n := frame_number(p)) is not None and first <= n <= last]
    boxes = read_boxes(annotation)
    check_row_count(name, boxes, annotation.name, images, frames)
    absent = np.all(np.isnan(boxes), axis=1)
    return make_sequence(name, frames, images, boxes, annotation.name, origin=1, layout="uav123", absent=absent)
