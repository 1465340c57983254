"""Read a CVAT for video XML file and a MOT Challenge file with Datumaro; print their boxes as JSON.

Run by the Python of Datumaro's own venv (``make datumaro-env``), never
vidtrack's: it imports nothing of vidtrack, so what it prints is what an
independent reader finds in the files.

    python datumaro_reader.py [--cvat FILE.xml] [--mot FILE.txt]

prints ``{"cvat": [...], "mot": [...]}``, one object per box:
``frame``, ``track_id``, ``box`` ``[x, y, w, h]`` and, for CVAT, ``label``,
``outside``, ``keyframe``; for MOT, ``score``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

from datumaro.components.annotation import AnnotationType
from datumaro.components.dataset import Dataset


def _boxes(dataset):
    labels = dataset.categories()[AnnotationType.label]
    for item in dataset:
        for ann in item.annotations:
            if ann.type != AnnotationType.bbox:
                continue
            yield item, ann, (labels[ann.label].name if ann.label is not None else None)


def read_cvat(path: Path) -> list[dict]:
    """Every box of the CVAT XML file ``path`` as Datumaro's ``cvat`` importer reads it."""
    dataset = Dataset.import_from(str(path), "cvat")
    rows = []
    for item, ann, label in _boxes(dataset):
        rows.append({"frame": int(item.attributes["frame"]), "track_id": int(ann.attributes["track_id"]),
                     "label": label, "box": [ann.x, ann.y, ann.w, ann.h],
                     "outside": bool(ann.attributes["outside"]), "keyframe": bool(ann.attributes["keyframe"])})
    return sorted(rows, key=lambda r: (r["track_id"], r["frame"]))


def read_mot(path: Path) -> list[dict]:
    """Every box of the MOT Challenge file ``path`` as Datumaro's ``mot_seq`` importer reads it.

    The file is laid out as a MOT sequence (``SEQ/gt/gt.txt``) in a
    temporary folder and read as results (``is_gt=False``: column 7 is a score).
    """
    with tempfile.TemporaryDirectory() as tmp:
        gt = Path(tmp) / "seq" / "gt"
        gt.mkdir(parents=True)
        shutil.copyfile(path, gt / "gt.txt")
        dataset = Dataset.import_from(tmp, "mot_seq", is_gt=False)
        rows = [{"frame": int(item.id), "track_id": int(ann.attributes["track_id"]),
                 "box": [ann.x, ann.y, ann.w, ann.h], "score": float(ann.attributes["score"])}
                for item, ann, _ in _boxes(dataset)]
    return sorted(rows, key=lambda r: (r["track_id"], r["frame"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cvat", type=Path)
    parser.add_argument("--mot", type=Path)
    args = parser.parse_args(argv)
    out = {}
    if args.cvat is not None:
        out["cvat"] = read_cvat(args.cvat)
    if args.mot is not None:
        out["mot"] = read_mot(args.mot)
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
