"""Benchmark datasets as they are downloaded: find the layout, list the sequences, read them.

Layouts (one reader each in :mod:`vidtrack.eval.layouts`):

=========  ====================================================================  ========
layout     folder                                                                pixels
=========  ====================================================================  ========
``otb``    ``<Seq>/img/`` + ``groundtruth_rect.txt`` (OTB-100's quirks); MIL      1-based;
           ``<seq>/imgs/`` + ``<seq>_gt.txt`` + ``<seq>_frames.txt``             MIL 0
``lasot``  ``<class>/<class>-<n>/img/`` + ``groundtruth.txt`` + flag files       1-based
``got10k`` ``<split>/list.txt``, ``GOT-10k_*/`` images + ``groundtruth.txt`` +   0-based
           ``absence.label`` + ``cover.label``
``uav123`` ``data_seq/UAV123/<seq>/`` + ``anno/UAV123/<seq>.txt`` (NaN rows)       1-based
``vot``    ``list.txt``, ``<seq>/color/`` (or images) + ``groundtruth.txt``      0-based
           (rectangles or polygons, reduced to bounding rectangles)
=========  ====================================================================  ========

The layout is detected from the folder (:func:`detect_layout`) or named.  The
trackers work in 0-based pixels: the init box is shifted by ``-origin`` and
every tracked box by ``+origin`` before it is written to a result file, so
result files use the benchmark's own convention.  :func:`read_dataset` reads
every sequence it can and reports each one it cannot with the reason;
:func:`load_dataset` stops at the first that cannot be read.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..errors import DatasetError
from .layouts import got10k, lasot, otb, uav123, vot
from .sequence import BenchmarkSequence, annotated_rows, check_init_box, parse_boxes, read_boxes, read_list
from .subsets import SUBSETS

__all__ = ["LAYOUTS", "BenchmarkSequence", "DatasetReading", "annotated_rows", "check_init_box", "detect_layout",
           "find_sequences", "is_sequence_folder", "load_dataset", "load_sequence", "parse_boxes", "read_boxes",
           "read_dataset", "read_names", "sequence_entries"]

#: Layout name -> its reader module, in the order :func:`detect_layout` tries them.
LAYOUTS = {"uav123": uav123, "got10k": got10k, "lasot": lasot, "vot": vot, "otb": otb}

load_sequence = otb.load_sequence


def is_sequence_folder(folder: str | Path) -> bool:
    """True when ``folder`` is one sequence of any layout."""
    folder = Path(folder)
    return folder.is_dir() and any(module.is_sequence(folder) for module in LAYOUTS.values())


def detect_layout(dataset: str | Path) -> str:
    """The layout of a dataset or sequence folder.

    Raises
    ------
    DatasetError
        When the folder does not exist or is no layout's.
    """
    dataset = Path(dataset)
    if not dataset.is_dir():
        raise DatasetError(f"no such dataset folder: {dataset}")
    for name, module in LAYOUTS.items():
        if module.is_sequence(dataset):
            return name
    for name, module in LAYOUTS.items():
        if module.is_dataset(dataset):
            return name
    raise DatasetError(f"no sequences in {dataset} (expected one of the layouts {', '.join(LAYOUTS)}: "
                       f"sub-folders with images and a ground-truth file)")


def sequence_entries(dataset: str | Path, layout: str | None = None) -> dict[str, Callable[[], BenchmarkSequence]]:
    """``{sequence name: loader}`` of a dataset folder in ``layout`` (detected when None).

    Raises
    ------
    DatasetError
        When the path does not exist, the layout is unknown, or it holds no sequence.
    """
    dataset = Path(dataset).resolve()  # absolute: jobs may run in other processes or machines
    if not dataset.is_dir():
        raise DatasetError(f"no such dataset folder: {dataset}")
    if layout is None:
        layout = detect_layout(dataset)
    elif layout not in LAYOUTS:
        raise DatasetError(f"unknown layout {layout!r}; layouts: {', '.join(LAYOUTS)}")
    found = LAYOUTS[layout].dataset_entries(dataset)
    if not found:
        raise DatasetError(f"no {layout} sequences in {dataset}")
    return found


def find_sequences(dataset: str | Path, layout: str | None = None) -> list[str]:
    """The sequence names of a dataset folder (see :func:`sequence_entries`)."""
    return list(sequence_entries(dataset, layout))


@dataclass
class DatasetReading:
    """The sequences read, in order, and ``{name: reason}`` for each that could not be."""

    sequences: list[BenchmarkSequence] = field(default_factory=list)
    errors: dict[str, str] = field(default_factory=dict)


def _matches(entries: dict, name: str) -> list[str]:
    """Entries named ``name`` (any case), else its targets ``name-1``, ``name-2`` ... (a two-target folder)."""
    if name in entries:
        return [name]
    lower = name.lower()
    exact = [n for n in entries if n.lower() == lower]
    if exact:
        return exact[:1]
    targets = re.compile(rf"^{re.escape(lower)}-\d+$")
    return [n for n in entries if targets.match(n.lower())]


def _some(names, shown: int = 12) -> str:
    """The first ``shown`` names, comma-separated, and how many there are in all when that is more."""
    names = list(names)
    more = f" ... ({len(names)} in all)" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


def _choose(entries: dict, names: list[str] | None, dataset: str | Path, *, subset: str | None = None
            ) -> tuple[list[str], dict[str, str]]:
    """The entries ``names`` select, in order, and ``{name: reason}`` for subset names not in the dataset."""
    if names is None:
        return list(entries), {}
    chosen: list[str] = []
    missing: dict[str, str] = {}
    for name in names:
        found = _matches(entries, name)
        if not found and subset is None:
            raise DatasetError(f"unknown sequence {name!r}; sequences in {dataset}: {_some(entries)}")
        if not found:
            missing[name] = f"sequence {name}: not in {dataset} (a sequence of the subset {subset})"
        chosen += [n for n in found if n not in chosen]
    return chosen, missing


def read_dataset(dataset: str | Path, names: list[str] | None = None, *, layout: str | None = None,
                 subset: str | None = None) -> DatasetReading:
    """Read the sequences of ``dataset`` (all, those in ``names`` or those of ``subset``, in that order).

    A name selects the sequence of that name (any case) or, failing that, the
    targets of a two-target folder (``Jogging`` selects ``Jogging-1`` and
    ``Jogging-2``).  ``subset`` is a published list of :data:`SUBSETS
    <vidtrack.eval.subsets.SUBSETS>` (``otb100``, ``lasot-test`` ...).  A
    sequence that cannot be read, or a subset's sequence the dataset lacks, is
    recorded in ``errors`` with the reason (``sequence NAME: ...``); the others
    are still read.

    Raises
    ------
    DatasetError
        For a missing folder, an unknown layout, subset or sequence name (the
        message lists the valid ones), or a folder with no sequence.
    """
    entries = sequence_entries(dataset, layout)
    if subset is not None:
        if subset not in SUBSETS:
            raise DatasetError(f"unknown subset {subset!r}; subsets: {', '.join(SUBSETS)}")
        names = SUBSETS[subset]
    chosen, missing = _choose(entries, names, dataset, subset=subset)
    reading = DatasetReading(errors=missing)
    for name in chosen:
        try:
            reading.sequences.append(entries[name]())
        except DatasetError as exc:
            reason = str(exc)
            reading.errors[name] = reason if reason.startswith(f"sequence {name}:") else f"sequence {name}: {reason}"
    return reading


def load_dataset(dataset: str | Path, names: list[str] | None = None, *, layout: str | None = None
                 ) -> list[BenchmarkSequence]:
    """Load the sequences of ``dataset`` (all, or those in ``names``, in that order).

    Raises
    ------
    DatasetError
        As :func:`read_dataset`, and for the first sequence that cannot be read.
    """
    entries = sequence_entries(dataset, layout)
    return [entries[name]() for name in _choose(entries, names, dataset)[0]]



def read_names(path: str | Path) -> list[str]:
    """Sequence names from a ``list.txt`` (one a line; blank lines and ``#`` comments ignored).

    Raises
    ------
    DatasetError
        When the file cannot be read or names no sequence.
    """
    names = read_list(Path(path))
    if not names:
        raise DatasetError(f"{path} names no sequence")
    return names
