"""OTB (Wu, Lim, Yang, "Object Tracking Benchmark", TPAMI 2015) and the original MIL layout.

OTB-100 as published::

    Girl/img/0001.jpg ...            frames, by number (Board: 00001.jpg; BlurCar1 starts at 0247.jpg)
    Girl/groundtruth_rect.txt        one x,y,w,h row per frame (tabs, commas or spaces), 1-based
    Jogging/groundtruth_rect.1.txt   two targets: scored as Jogging-1 and Jogging-2
    Human4/groundtruth_rect.2.txt    one target, stored as target 2 (the .1 file is empty)
    Girl/cfg.mat                     ignored

Five OTB folders hold more images than ground-truth rows; the rows belong to
the frame numbers in :data:`OTB_FRAME_RANGES` (the benchmark's own
configuration).  MIL (Babenko, Yang, Belongie, "Visual Tracking with Online
Multiple Instance Learning", CVPR 2009)::

    sylv/imgs/img00000.png ...       frames, numbered
    sylv/sylv_gt.txt                 one x,y,w,h row per annotated-or-not frame, 0-based
    sylv/sylv_frames.txt             "start,end": the frame numbers the paper ran on

An OTB folder holding ``mil_frames.txt`` or a ``*_frames.txt`` is MIL data
copied into the OTB layout: 0-based (MILTrack is C++/OpenCV code).  When a MIL
folder holds more images than rows, the rows belong to the images whose
number lies in the frames range; the evaluated frames are those of the range,
from its first annotated row.
"""

from __future__ import annotations

import re
from functools import partial
from pathlib import Path

from ...errors import DatasetError
from ...types import split_numbers
from ..sequence import (BenchmarkSequence, check_row_count, frame_number, list_images, make_sequence, read_boxes,
                        read_text)

OTB_IMAGES, MIL_IMAGES = "img", "imgs"
OTB_GROUND_TRUTH = "groundtruth_rect.txt"
MIL_FRAMES = "mil_frames.txt"
_TARGET_FILE = re.compile(r"^groundtruth_rect\.(\d+)\.txt$")

#: OTB-100 folders with more images than ground-truth rows: the first and last
#: frame number the rows belong to (the benchmark's configSeqs).
OTB_FRAME_RANGES: dict[str, tuple[int, int]] = {
    "david": (300, 770),
    "diving": (1, 215),
    "football1": (1, 74),
    "freeman3": (1, 460),
    "freeman4": (1, 283),
}


def _image_folder(folder: Path) -> Path | None:
    for name in (OTB_IMAGES, MIL_IMAGES):
        if (folder / name).is_dir():
            return folder / name
    return None


def is_sequence(folder: Path) -> bool:
    """True when ``folder`` has an ``img/`` or ``imgs/`` image folder."""
    return Path(folder).is_dir() and _image_folder(Path(folder)) is not None


def is_dataset(folder: Path) -> bool:
    """True when a sub-folder of ``folder`` is an OTB or MIL sequence."""
    return any(is_sequence(p) for p in Path(folder).iterdir() if p.is_dir())


def _mil_file(folder: Path, suffix: str) -> Path | None:
    """``<name>_gt.txt`` / ``<name>_frames.txt``, preferring the folder's own name."""
    for own in (folder / f"{folder.name}{suffix}", folder / f"{folder.name.lower()}{suffix}"):
        if own.is_file():
            return own
    candidates = sorted(p for p in folder.glob(f"*{suffix}") if p.is_file())
    return candidates[0] if len(candidates) == 1 else None


def _target_files(folder: Path) -> list[tuple[int, Path]]:
    """``groundtruth_rect.N.txt`` files that hold rows, by target number."""
    found = []
    for path in folder.iterdir():
        match = _TARGET_FILE.match(path.name)
        if match and path.is_file() and read_text(path).strip():
            found.append((int(match.group(1)), path))
    return sorted(found)


def entries(folder: Path) -> dict[str, partial]:
    """``{name: loader}`` for one sequence folder: one per target (``Jogging-1``, ``Jogging-2``)."""
    folder = Path(folder)
    if (folder / OTB_GROUND_TRUTH).is_file() or _mil_file(folder, "_gt.txt") is not None:
        return {folder.name: partial(load_sequence, folder)}
    targets = _target_files(folder)
    if len(targets) == 1:
        return {folder.name: partial(load_sequence, folder, ground_truth=targets[0][1])}
    if targets:
        return {f"{folder.name}-{n}": partial(load_sequence, folder, ground_truth=path, name=f"{folder.name}-{n}")
                for n, path in targets}
    return {folder.name: partial(load_sequence, folder)}  # reports the missing ground truth


def dataset_entries(root: Path) -> dict[str, partial]:
    """Every sequence of an OTB/MIL dataset folder (or the folder itself if it is one), by name."""
    root = Path(root)
    if is_sequence(root):
        return entries(root)
    found: dict[str, partial] = {}
    for folder in sorted((p for p in root.iterdir() if is_sequence(p)), key=lambda p: p.name.lower()):
        found.update(entries(folder))
    return found


def _read_frames_range(path: Path) -> tuple[int, int]:
    numbers = split_numbers(read_text(path))
    try:
        start, end = (int(float(p)) for p in numbers[:2])
    except ValueError:
        raise DatasetError(f"{path}: expected 'start,end' frame numbers") from None
    if end < start:
        raise DatasetError(f"{path}: expected 'start,end' frame numbers with start <= end")
    return start, end


def load_sequence(folder: str | Path, *, ground_truth: Path | None = None, name: str | None = None
                  ) -> BenchmarkSequence:
    """Load one OTB or MIL sequence folder (``ground_truth``: one target's file of a multi-target folder).

    Raises
    ------
    DatasetError
        No image folder or no images, no ground truth, a ground truth whose
        row count matches neither the images nor a published or MIL frames
        range, or no annotated row.
    """
    folder = Path(folder).resolve()  # absolute: jobs may run in other processes or machines
    name = name or folder.name
    images_dir = _image_folder(folder)
    if images_dir is None:
        raise DatasetError(f"sequence {name}: no img/ or imgs/ folder in {folder}")
    images = list_images(images_dir)
    if not images:
        raise DatasetError(f"sequence {name}: {images_dir} holds no images")

    gt_path = ground_truth or (folder / OTB_GROUND_TRUTH if (folder / OTB_GROUND_TRUTH).is_file()
                               else _mil_file(folder, "_gt.txt"))
    if gt_path is None:
        raise DatasetError(f"sequence {name}: images but no ground truth "
                           f"({OTB_GROUND_TRUTH} or {folder.name}_gt.txt) in {folder}")
    frames_path = folder / MIL_FRAMES if (folder / MIL_FRAMES).is_file() else _mil_file(folder, "_frames.txt")
    is_mil = frames_path is not None or images_dir.name == MIL_IMAGES
    boxes = read_boxes(gt_path)

    frames_range = _read_frames_range(frames_path) if frames_path is not None else None
    if frames_range is None and len(boxes) != len(images):
        frames_range = OTB_FRAME_RANGES.get(folder.name.lower())
    numbers = [frame_number(p) for p in images]

    def in_range(number: int | None) -> bool:
        return frames_range is not None and number is not None and frames_range[0] <= number <= frames_range[1]

    files = images
    if len(boxes) != len(images) and frames_range is not None:
        files = [p for p, n in zip(images, numbers) if in_range(n)]
    check_row_count(name, boxes, gt_path.name, files if len(files) == len(boxes) else images, images_dir)

    run_range = (0, len(files))
    if frames_range is not None and is_mil:
        inside = [i for i, p in enumerate(files) if in_range(frame_number(p))]
        if inside:
            run_range = (inside[0], inside[-1] + 1)
    return make_sequence(name, folder, files, boxes, gt_path.name, origin=0 if is_mil else 1,
                         layout="mil" if images_dir.name == MIL_IMAGES else "otb", run_range=run_range)
