"""The evaluation report: a table (printed and ``summary.md``) and ``summary.json``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..errors import OutputError

COLUMNS = (("auc", "AUC", "{:.3f}"), ("precision20", "Prec@20", "{:.3f}"), ("pascal", "PASCAL", "{:.3f}"),
           ("center_error", "CLE px", "{:.1f}"), ("fps", "fps", "{:.1f}"))


def _cell(value: Any, fmt: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return fmt.format(value)


def format_table(summary: dict[str, dict[str, dict[str, Any]]]) -> str:
    """A Markdown table: one row per filter and sequence, then the filter's mean.

    ``AUC`` is the OTB success AUC, ``Prec@20`` the fraction of frames with
    centre error <= 20 px, ``PASCAL`` the fraction with IoU > 0.5, ``CLE``
    the mean centre-location error and ``fps`` the tracker's speed in that run.
    """
    header = ["filter", "sequence", *(title for _, title, _ in COLUMNS)]
    rows = []
    for name, per_sequence in summary.items():
        for sequence, row in per_sequence.items():
            if sequence == "mean":
                continue
            if "error" in row:
                rows.append([name, sequence, f"FAILED: {row['error']}"[:80], "", "", "", ""])
            else:
                rows.append([name, sequence, *(_cell(row.get(k), fmt) for k, _, fmt in COLUMNS)])
        mean = per_sequence.get("mean", {})
        label = "**mean**" if not mean.get("failed") else f"**mean** ({len(mean['failed'])} failed)"
        rows.append([name, label, *(_cell(mean.get(k), fmt) for k, _, fmt in COLUMNS)])
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    right = [False, False] + [True] * len(COLUMNS)

    def line(cells):
        return "| " + " | ".join(str(c).rjust(w) if r else str(c).ljust(w)
                                 for c, w, r in zip(cells, widths, right)) + " |"

    rule = "|" + "|".join(("-" * (w + 1) + ":") if r else ("-" * (w + 2)) for w, r in zip(widths, right)) + "|"
    return "\n".join([line(header), rule, *(line(r) for r in rows)])


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    return value


def write_summary(out: str | Path, summary: dict[str, dict[str, dict[str, Any]]]) -> tuple[Path, Path]:
    """Write ``OUT/summary.json`` (non-finite numbers as null) and ``OUT/summary.md``."""
    out = Path(out)
    json_path, md_path = out / "summary.json", out / "summary.md"
    try:
        out.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(_finite_or_none(summary), indent=2) + "\n", encoding="utf-8")
        md_path.write_text("# vidtrack evaluation\n\n" + format_table(summary) + "\n\n"
                           "AUC: OTB success AUC (mean over IoU thresholds 0, 0.05, ..., 1); Prec@20: fraction "
                           "of frames with centre error <= 20 px; PASCAL: fraction with IoU > 0.5; CLE: mean "
                           "centre-location error; fps: tracker frames per second, decoding excluded. Only "
                           "annotated ground-truth frames are scored.\n", encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write the summary in {out}: {exc.strerror or exc}") from None
    return json_path, md_path
