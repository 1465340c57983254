"""``vidtrack eval --compare DIR_A DIR_B``: the change in success AUC between two evaluations.

Reads ``summary.json`` of each folder (written by ``vidtrack eval --out DIR``)
and tables, per tracker and sequence both hold, ``AUC(B) - AUC(A)``; each
tracker's mean row averages the sequences both scored, so the two means are
over the same sequences.  A change of at least :data:`FLAG` is marked, so a
regression is visible at once.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..errors import UsageError

#: |delta AUC| from which a row is marked ``worse`` / ``better``.
FLAG = 0.05
#: Keys of summary.json that are not trackers.
NOT_FILTERS = {"by_attribute"}


def read_summary(folder: str | Path) -> dict[str, dict[str, dict[str, Any]]]:
    """``{filter: {sequence: row}}`` from ``FOLDER/summary.json`` (the ``mean`` rows dropped).

    Raises
    ------
    UsageError
        When the folder has no readable summary.
    """
    path = Path(folder) / "summary.json"
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UsageError(f"{folder} has no summary.json (write one with vidtrack eval ... --out {folder})") from None
    except (OSError, ValueError) as exc:
        raise UsageError(f"cannot read {path}: {exc}") from None
    if not isinstance(document, dict):
        raise UsageError(f"{path} is not a vidtrack eval summary")
    return {name: {seq: row for seq, row in rows.items() if seq != "mean" and isinstance(row, dict)}
            for name, rows in document.items() if name not in NOT_FILTERS and isinstance(rows, dict)}


def _auc(row: dict[str, Any] | None) -> float | None:
    value = None if row is None else row.get("auc")
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None


def compare(a: dict[str, dict[str, dict[str, Any]]], b: dict[str, dict[str, dict[str, Any]]]) -> list[dict]:
    """Rows ``{filter, sequence, auc_a, auc_b, delta, only}``, per tracker its sequences then its ``mean``.

    Trackers and sequences in the order of ``a`` then those only in ``b``; a
    side that lacks the pair (``only`` is then ``"A"`` or ``"B"``) or failed
    on it has ``None`` and so has ``delta``.  The mean is over the sequences
    both sides scored.
    """
    out = []
    for name in list(a) + [n for n in b if n not in a]:
        rows_a, rows_b = a.get(name, {}), b.get(name, {})
        both = []
        for sequence in list(rows_a) + [s for s in rows_b if s not in rows_a]:
            auc_a, auc_b = _auc(rows_a.get(sequence)), _auc(rows_b.get(sequence))
            delta = None if auc_a is None or auc_b is None else auc_b - auc_a
            if delta is not None:
                both.append((auc_a, auc_b))
            only = None if (sequence in rows_a) == (sequence in rows_b) else ("A" if sequence in rows_a else "B")
            out.append({"filter": name, "sequence": sequence, "auc_a": auc_a, "auc_b": auc_b, "delta": delta,
                        "only": only})
        if both:
            mean_a, mean_b = (sum(p[i] for p in both) / len(both) for i in (0, 1))
            out.append({"filter": name, "sequence": "mean", "auc_a": mean_a, "auc_b": mean_b,
                        "delta": mean_b - mean_a, "sequences": len(both)})
        else:
            out.append({"filter": name, "sequence": "mean", "auc_a": None, "auc_b": None, "delta": None,
                        "sequences": 0})
    return out


def format_comparison(rows: list[dict], label_a: str = "A", label_b: str = "B") -> str:
    """A Markdown table of :func:`compare`'s rows; ``|delta| >= FLAG`` marked ``worse`` / ``better``.

    Pairs held by one side only are not tabled but counted in a last line.
    """
    from .report import _markdown

    def cell(value, fmt):
        return "-" if value is None else fmt.format(value)

    table = []
    only: dict[str, int] = {}
    for row in rows:
        if row.get("only"):
            only[row["only"]] = only.get(row["only"], 0) + 1
            continue
        if row["sequence"] == "mean" and row["sequences"] == 0 and not any(
                r["filter"] == row["filter"] and r["sequence"] != "mean" and not r.get("only") for r in rows):
            continue  # a tracker only one side ran
        delta = row["delta"]
        mark = "" if delta is None or abs(delta) < FLAG else ("worse" if delta < 0 else "better")
        if delta is None and row["sequence"] != "mean":
            mark = f"failed in {label_a if row['auc_a'] is None else label_b}"
        sequence = row["sequence"] if row["sequence"] != "mean" else f"**mean** ({row['sequences']} seq.)"
        table.append([row["filter"], sequence, cell(row["auc_a"], "{:.3f}"), cell(row["auc_b"], "{:.3f}"),
                      cell(delta, "{:+.3f}"), mark])
    header = ["filter", "sequence", f"AUC {label_a}", f"AUC {label_b}", "change", ""]
    text = _markdown(header, table, [False, False, True, True, True, False])
    label = {"A": label_a, "B": label_b}
    notes = [f"{n} tracker/sequence pair{'s' * (n != 1)} only in {label[side]}" for side, n in sorted(only.items())]
    return text + ("\n(" + "; ".join(notes) + ": not compared)" if notes else "")
