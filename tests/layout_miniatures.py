"""Miniatures of the benchmark layouts as downloaded, built in a temporary folder from the shared sequences.

Frames are hard-linked (copied where linking fails) from
``../shared/data/sequences``, never into the repository.  Each builder
returns the folder to pass to ``vidtrack eval`` and what a reader must find.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

SEQUENCES = Path(__file__).resolve().parents[2] / "shared/data/sequences"
FRAMES = 12  # frames per miniature sequence


def link(source: Path, target: Path) -> None:
    """Hard-link ``source`` to ``target`` (a copy when the file system refuses)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError:
        shutil.copyfile(source, target)


def shared(name: str, count: int = FRAMES) -> tuple[list[Path], np.ndarray]:
    """The first ``count`` frames of a shared OTB sequence and their 1-based ground truth."""
    folder = SEQUENCES / name
    frames = sorted((folder / "img").iterdir())[:count]
    rows = [line for line in (folder / "groundtruth_rect.txt").read_text().splitlines() if line.strip()]
    boxes = np.array([[float(v) for v in row.replace("\t", ",").split(",")] for row in rows[:count]])
    return frames, boxes


def _rows(boxes: np.ndarray, separator: str = ",") -> str:
    return "".join(separator.join(f"{v:g}" for v in row) + "\n" for row in boxes)


def _link_frames(frames: list[Path], folder: Path, pattern: str, first: int = 1) -> None:
    for k, frame in enumerate(frames):
        link(frame, folder / (pattern.format(first + k) + frame.suffix))


def build_otb(root: Path) -> Path:
    """OTB-100's quirks: a David-like range, two-target Jogging, Human4's .2 file, delimiters, names, cfg.mat."""
    girl, girl_gt = shared("Girl", 310)
    jog, jog_gt = shared("Jogging")
    data = root / "otb"
    # David: images 0001..0310, ground truth for 0300..0310 only (OTB's David is 300..770 of 770 images)
    _link_frames(girl, data / "David/img", "{:04d}")
    (data / "David/groundtruth_rect.txt").write_text(_rows(girl_gt[299:310]))
    # Jogging: two targets, tab-separated
    _link_frames(jog, data / "Jogging/img", "{:04d}")
    (data / "Jogging/groundtruth_rect.1.txt").write_text(_rows(jog_gt, "\t"))
    target2 = jog_gt + [40, 0, 0, 0]
    (data / "Jogging/groundtruth_rect.2.txt").write_text(_rows(target2, "\t"))
    # Human4: an empty .1 file and the target in .2
    girl, girl_gt = girl[:FRAMES], girl_gt[:FRAMES]
    _link_frames(girl, data / "Human4/img", "{:04d}")
    (data / "Human4/groundtruth_rect.1.txt").write_text("")
    (data / "Human4/groundtruth_rect.2.txt").write_text(_rows(girl_gt))
    # Board: five-digit names and a cfg.mat
    _link_frames(girl, data / "Board/img", "{:05d}")
    (data / "Board/groundtruth_rect.txt").write_text(_rows(girl_gt))
    (data / "Board/cfg.mat").write_bytes(b"MATLAB 5.0 MAT-file\x00")
    # BlurCar1: starts at 0247.jpg, commas with one row of spaces
    _link_frames(girl, data / "BlurCar1/img", "{:04d}", first=247)
    text = _rows(girl_gt).splitlines(keepends=True)
    text[3] = text[3].replace(",", " ")
    (data / "BlurCar1/groundtruth_rect.txt").write_text("".join(text))
    return data


def build_lasot(root: Path) -> Path:
    """A LaSOT root with one class folder of two sequences and their flag files."""
    girl, girl_gt = shared("Girl")
    data = root / "lasot"
    for n in (1, 2):
        folder = data / "person" / f"person-{n}"
        _link_frames(girl, folder / "img", "{:08d}")
        (folder / "groundtruth.txt").write_text(_rows(girl_gt))
        occlusion = ["0"] * FRAMES
        out_of_view = ["0"] * FRAMES
        occlusion[6] = "1"
        out_of_view[9] = "1"
        (folder / "full_occlusion.txt").write_text(",".join(occlusion) + "\n")
        (folder / "out_of_view.txt").write_text(",".join(out_of_view) + "\n")
        (folder / "nlp.txt").write_text("a girl\n")
    return data


def build_got10k(root: Path) -> Path:
    """A GOT-10k val split (list.txt, absence.label, cover.label) and a test-split sequence."""
    girl, girl_gt = shared("Girl")
    data = root / "got10k" / "val"
    names = ["GOT-10k_Val_000001", "GOT-10k_Val_000002"]
    for name in names:
        folder = data / name
        _link_frames(girl, folder, "{:08d}")
        boxes = girl_gt - [1, 1, 0, 0]  # GOT-10k is 0-based
        absence = np.zeros(FRAMES, int)
        absence[8] = 1
        boxes[8] = 0  # GOT-10k's absent rows
        (folder / "groundtruth.txt").write_text(_rows(boxes))
        (folder / "absence.label").write_text("".join(f"{a}\n" for a in absence))
        (folder / "cover.label").write_text("".join(f"{0 if a else 8}\n" for a in absence))
        (folder / "cut_by_image.label").write_text("0\n" * FRAMES)
        (folder / "meta_info.ini").write_text("[METAINFO]\nobject_class: person\nresolution: (128, 96)\n")
    (data / "list.txt").write_text("\n".join(names) + "\n")
    test = root / "got10k" / "test" / "GOT-10k_Test_000001"
    _link_frames(girl, test, "{:08d}")
    (test / "groundtruth.txt").write_text(_rows(girl_gt[:1] - [1, 1, 0, 0]))
    (test.parent / "list.txt").write_text("GOT-10k_Test_000001\n")
    return data


def build_uav123(root: Path) -> Path:
    """``Dataset_UAV123/UAV123`` with ``data_seq/`` and ``anno/``, NaN rows while out of view, a split sequence."""
    girl, girl_gt = shared("Girl")
    base = root / "Dataset_UAV123" / "UAV123"
    _link_frames(girl, base / "data_seq/UAV123/person1", "{:06d}")
    boxes = girl_gt.copy()
    boxes[4:6] = np.nan
    (base / "anno/UAV123/att").mkdir(parents=True)
    (base / "anno/UAV123/person1.txt").write_text(_rows(boxes).replace("nan", "NaN"))
    # car16_1: frames 1..415 of the folder car16 (which holds more)
    girl, girl_gt = shared("Girl", 420)
    _link_frames(girl, base / "data_seq/UAV123/car16", "{:06d}")
    (base / "anno/UAV123/car16_1.txt").write_text(_rows(girl_gt[:415]))
    return root / "Dataset_UAV123"


def polygon(box: np.ndarray) -> list[float]:
    """A 0-based box as VOT's four-corner polygon, with the corners slightly inside its sides."""
    x, y, w, h = box
    return [x, y + 1, x + w - 1, y, x + w, y + h - 1, x + 1, y + h]


def build_vot(root: Path) -> Path:
    """A VOT folder: list.txt, one sequence with polygons in color/, one with rectangles and images in place."""
    girl, girl_gt = shared("Girl")
    data = root / "vot"
    boxes = girl_gt - [1, 1, 0, 0]
    _link_frames(girl, data / "girl/color", "{:08d}")
    (data / "girl/groundtruth.txt").write_text(
        "".join(",".join(f"{v:g}" for v in polygon(b)) + "\n" for b in boxes))
    (data / "girl/sequence").write_text("channels.color=color/%08d.jpg\n")
    _link_frames(girl, data / "girl2", "{:08d}")
    (data / "girl2/groundtruth.txt").write_text(_rows(boxes))
    (data / "list.txt").write_text("girl\ngirl2\n")
    return data
