"""OTB challenge attributes: read ``attr_list.txt`` and break the success AUC down by attribute.

The OTB benchmark (Wu, Lim, Yang, "Online Object Tracking: A Benchmark",
CVPR 2013) tags every sequence with the challenges it holds and reports the
success plot per tag; it shows *why* a tracker fails.  Its ``attr_list.txt``
holds one sequence per line: the name, a tab, comma-separated tags::

    David	IV, SV, OCC, DEF, MB, IPR, OPR
    Suv	OCC, IPR, OV

The per-attribute score of a tracker is the mean success AUC over the
sequences carrying that tag (every sequence weighs the same, as in OTB's
attribute plots), with the number of sequences it averages.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Mapping

from ..errors import DatasetError

ATTRIBUTE_FILE = "attr_list.txt"
#: OTB's tags in its own order, with their names.
OTB_ATTRIBUTES = {
    "IV": "illumination variation", "SV": "scale variation", "OCC": "occlusion", "DEF": "deformation",
    "MB": "motion blur", "FM": "fast motion", "IPR": "in-plane rotation", "OPR": "out-of-plane rotation",
    "OV": "out of view", "BC": "background clutter", "LR": "low resolution",
}
_TAG = re.compile(r"^[A-Za-z0-9_-]+$")


def parse_attributes(text: str, *, source: str = ATTRIBUTE_FILE) -> dict[str, tuple[str, ...]]:
    """``attr_list.txt`` text -> ``{sequence: (tag, ...)}`` (tags upper-cased, in file order).

    The name is separated from the tags by a tab (OTB's format) or, failing
    that, by the first run of spaces; tags by commas (spaces around them are
    ignored).  Blank lines and lines starting with ``#`` are skipped.

    Raises
    ------
    DatasetError
        On a line without tags, a tag that is not a word, or a sequence listed twice.
    """
    table: dict[str, tuple[str, ...]] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        name, sep, rest = line.partition("\t")
        if not sep:
            name, sep, rest = line.partition(" ")
        name, rest = name.strip(), rest.strip()
        if not rest:
            raise DatasetError(f"{source}, line {number}: expected 'name<TAB>TAG, TAG, ...', got {line[:60]!r}")
        tags = [t.strip().upper() for t in rest.split(",") if t.strip()]
        bad = [t for t in tags if not _TAG.match(t)]
        if bad or not tags:
            raise DatasetError(f"{source}, line {number}: {bad[0] if bad else rest!r} is not an attribute tag")
        if name in table:
            raise DatasetError(f"{source}, line {number}: sequence {name!r} listed twice")
        table[name] = tuple(dict.fromkeys(tags))
    return table


def read_attributes(path: str | Path) -> dict[str, tuple[str, ...]]:
    """Read an attribute file (see :func:`parse_attributes`)."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise DatasetError(f"cannot read the attribute file {path}: {exc.strerror or exc}") from None
    return parse_attributes(text, source=str(path))


def find_attribute_file(dataset: str | Path) -> Path | None:
    """``DATASET/attr_list.txt``, or the parent's when ``dataset`` is one sequence folder; else None."""
    dataset = Path(dataset)
    for folder in (dataset, dataset.parent):
        if (folder / ATTRIBUTE_FILE).is_file():
            return folder / ATTRIBUTE_FILE
    return None


def sequence_tags(attributes: Mapping[str, tuple[str, ...]], sequence: str) -> tuple[str, ...]:
    """The tags of ``sequence`` (exact name, else case-insensitive), or ``()``."""
    if sequence in attributes:
        return attributes[sequence]
    lower = {k.lower(): v for k, v in attributes.items()}
    return lower.get(sequence.lower(), ())


def tag_order(tags) -> list[str]:
    """OTB's tags in OTB's order, then any others alphabetically."""
    tags = set(tags)
    return [t for t in OTB_ATTRIBUTES if t in tags] + sorted(tags - set(OTB_ATTRIBUTES))


def by_attribute(summary: Mapping[str, Mapping[str, Mapping[str, Any]]],
                 attributes: Mapping[str, tuple[str, ...]]) -> dict[str, dict[str, dict[str, Any]]]:
    """``{filter: {TAG: {"auc": mean AUC, "sequences": n}}}`` over the sequences carrying each tag.

    Only tags that some evaluated sequence carries appear; a failed sequence
    (AUC ``None``) is left out of the mean and the count.  Tags are in
    :func:`tag_order`.
    """
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for name, rows in summary.items():
        values: dict[str, list[float]] = {}
        for sequence, row in rows.items():
            if sequence == "mean":
                continue
            for tag in sequence_tags(attributes, sequence):
                values.setdefault(tag, [])
                auc = row.get("auc")
                if auc is not None and math.isfinite(auc):
                    values[tag].append(float(auc))
        out[name] = {tag: {"auc": sum(values[tag]) / len(values[tag]) if values[tag] else None,
                           "sequences": len(values[tag])} for tag in tag_order(values)}
    return out
