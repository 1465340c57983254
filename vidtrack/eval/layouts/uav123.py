"""UAV123 (Mueller, Smith, Ghanem, "A Benchmark and Simulator for UAV Tracking", ECCV 2016).

::

    Dataset_UAV123/UAV123/data_seq/UAV123/bike1/000001.jpg ...   frames
    Dataset_UAV123/UAV123/anno/UAV123/bike1.txt                  one x,y,w,h row per frame, 1-based;
                                                                 NaN,NaN,NaN,NaN while out of view
    Dataset_UAV123/UAV123/anno/UAV20L/...                        the long-term subset, same layout

The dataset folder is the one holding ``anno/`` and ``data_seq/`` (or its
parent); the subset is ``UAV123`` when present, else the only one there.
A sequence is an annotation file whose name is a frame folder; the split
sequences (``bird1_1`` ...) cover a frame range of one folder and are not read.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from ...errors import DatasetError
from ..sequence import BenchmarkSequence, check_row_count, make_sequence, read_boxes, require_images


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
    return {name: partial(load_sequence, base / "data_seq" / subset / name, anno / f"{name}.txt") for name in names}


def load_sequence(frames: Path, annotation: Path) -> BenchmarkSequence:
    """Read one UAV123 sequence from its frame folder and annotation file.

    Raises
    ------
    DatasetError
        No frame folder (a split sequence) or no images, a row count that is
        not the image count, or no annotated row.
    """
    frames, name = Path(frames).resolve(), Path(annotation).stem
    if not frames.is_dir():
        raise DatasetError(f"sequence {name}: no frame folder {frames} (split sequences are not read)")
    images = require_images(name, frames)
    boxes = read_boxes(annotation)
    check_row_count(name, boxes, annotation.name, images, frames)
    absent = np.all(np.isnan(boxes), axis=1)
    return make_sequence(name, frames, images, boxes, annotation.name, origin=1, layout="uav123", absent=absent)
