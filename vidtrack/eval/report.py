"""The evaluation report: tables (printed and ``summary.md``) and ``summary.json``.

Three tables: the scores per tracker and sequence (:func:`format_table`), the
mean success AUC per OTB attribute (:func:`format_attribute_table`) and
whether the confidence can be trusted (:func:`format_confidence_table`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..errors import OutputError

COLUMNS = (("auc", "AUC", "{:.3f}"), ("precision20", "Prec@20", "{:.3f}"), ("norm_precision", "NormPrec", "{:.3f}"),
           ("pascal", "PASCAL", "{:.3f}"), ("center_error", "CLE px", "{:.1f}"), ("fps", "fps", "{:.1f}"))
#: GOT-10k's columns, shown when a row has them.
GOT10K_COLUMNS = (("ao", "AO", "{:.3f}"), ("sr50", "SR0.5", "{:.3f}"), ("sr75", "SR0.75", "{:.3f}"))


def score_columns(summary: dict[str, dict[str, dict[str, Any]]]) -> tuple[tuple[str, str, str], ...]:
    """The table's columns: :data:`COLUMNS`, and GOT-10k's before ``fps`` when any row has them."""
    has_got = any("ao" in row for per in summary.values() for row in per.values())
    return COLUMNS[:-1] + GOT10K_COLUMNS + COLUMNS[-1:] if has_got else COLUMNS


def _cell(value: Any, fmt: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return fmt.format(value)


def format_table(summary: dict[str, dict[str, dict[str, Any]]]) -> str:
    """A Markdown table: one row per filter and sequence, then the filter's mean.

    ``AUC`` is the OTB success AUC, ``Prec@20`` the fraction of frames with
    centre error <= 20 px, ``NormPrec`` LaSOT's normalised precision,
    ``PASCAL`` the fraction with IoU > 0.5, ``CLE`` the mean centre-location
    error, ``AO``, ``SR0.5`` and ``SR0.75`` GOT-10k's (on its sequences; the
    mean row pools their frames) and ``fps`` the tracker's speed in that run.
    """
    columns = score_columns(summary)
    header = ["filter", "sequence", *(title for _, title, _ in columns)]
    rows = []
    for name, per_sequence in summary.items():
        for sequence, row in per_sequence.items():
            if sequence == "mean":
                continue
            if "error" in row:
                rows.append([name, sequence, f"FAILED: {row['error']}"[:80], *[""] * (len(columns) - 1)])
            else:
                rows.append([name, sequence, *(_cell(row.get(k), fmt) for k, _, fmt in columns)])
        mean = per_sequence.get("mean", {})
        label = "**mean**" if not mean.get("failed") else f"**mean** ({len(mean['failed'])} failed)"
        rows.append([name, label, *(_cell(mean.get(k), fmt) for k, _, fmt in columns)])
    return _markdown(header, rows, [False, False] + [True] * len(columns))


def _markdown(header: list[str], rows: list[list[Any]], right: list[bool]) -> str:
    """A Markdown table with padded columns (``right``: right-aligned columns)."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(cells):
        return "| " + " | ".join(str(c).rjust(w) if r else str(c).ljust(w)
                                 for c, w, r in zip(cells, widths, right)) + " |"

    rule = "|" + "|".join(("-" * (w + 1) + ":") if r else ("-" * (w + 2)) for w, r in zip(widths, right)) + "|"
    return "\n".join([line(header), rule, *(line(r) for r in rows)])


def format_attribute_table(by_attribute: dict[str, dict[str, dict[str, Any]]],
                           summary: dict[str, dict[str, dict[str, Any]]] | None = None) -> str:
    """One row per filter, one column per attribute: mean success AUC over that attribute's sequences.

    Column headers give the tag and, in brackets, how many sequences carry it;
    with ``summary`` a last column ``all`` repeats the filter's mean AUC.
    """
    from .attributes import tag_order

    tags = tag_order({t for per in by_attribute.values() for t in per})
    counts = {t: max(per[t]["sequences"] for per in by_attribute.values() if t in per) for t in tags}
    header = ["filter", *(f"{t} ({counts[t]})" for t in tags)] + (["all"] if summary is not None else [])
    rows = []
    for name, per in by_attribute.items():
        row = [name, *(_cell(per.get(t, {}).get("auc"), "{:.3f}") for t in tags)]
        if summary is not None:
            row.append(_cell(summary.get(name, {}).get("mean", {}).get("auc"), "{:.3f}"))
        rows.append(row)
    return _markdown(header, rows, [False] + [True] * (len(header) - 1))


CONFIDENCE_COLUMNS = (("lost_rate", "lost", "{:.3f}"), ("false_lost", "false lost", "{:.3f}"),
                      ("missed_loss", "missed loss", "{:.3f}"), ("confidence_auc", "conf. ROC AUC", "{:.3f}"),
                      ("ece", "ECE", "{:.3f}"))


def format_confidence_table(summary: dict[str, dict[str, dict[str, Any]]]) -> str:
    """One row per filter (its frames pooled over the sequences), plus OpenCV's ``ok`` flag rows.

    ``lost``: fraction of frames marked lost; ``false lost``: of those, the
    fraction with IoU > 0; ``missed loss``: of the frames marked tracking, the
    fraction with IoU = 0; ``conf. ROC AUC``: the confidence as a predictor of
    IoU > 0.5; ``ECE``: the expected calibration error of the confidence read
    as the probability of IoU > 0.5 (see :mod:`vidtrack.eval.confidence`).
    """
    header = ["filter", *(title for _, title, _ in CONFIDENCE_COLUMNS)]
    rows = []
    for name, per_sequence in summary.items():
        mean = per_sequence.get("mean", {})
        rows.append([name, *(_cell(mean.get(k), fmt) for k, _, fmt in CONFIDENCE_COLUMNS)])
        if isinstance(mean.get("ok_flag"), dict):
            rows.append([f"{name} (OpenCV ok flag)",
                         *(_cell(mean["ok_flag"].get(k), fmt) for k, _, fmt in CONFIDENCE_COLUMNS)])
    return _markdown(header, rows, [False] + [True] * len(CONFIDENCE_COLUMNS))


CONFIDENCE_NOTE = ("Confidence (frames of all sequences pooled, init frame excluded): lost = fraction of "
                   "frames marked lost; false lost = of those, the fraction whose box still overlaps the "
                   "target (IoU > 0); missed loss = of the frames marked tracking, the fraction with IoU = 0; "
                   "conf. ROC AUC = area under the ROC curve of the confidence predicting IoU > 0.5 (0.5 = "
                   "chance); ECE = expected calibration error of the confidence as P(IoU > 0.5) (ten equal "
                   "confidence bins; summary.json's \"reliability\" holds them). OpenCV ok flag rows: the same for OpenCV's own update() flag (lost where it "
                   "returns False).")


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    return value


def write_summary(out: str | Path, summary: dict[str, dict[str, dict[str, Any]]],
                  by_attribute: dict[str, dict[str, dict[str, Any]]] | None = None) -> tuple[Path, Path]:
    """Write ``OUT/summary.json`` (non-finite numbers as null) and ``OUT/summary.md``.

    ``by_attribute`` (see :func:`vidtrack.eval.attributes.by_attribute`), when
    given, is stored under the JSON's ``"by_attribute"`` key and tabled.
    """
    out = Path(out)
    json_path, md_path = out / "summary.json", out / "summary.md"
    document = dict(summary)
    extra = "\n" + format_confidence_table(summary) + "\n\n" + CONFIDENCE_NOTE + "\n"
    if by_attribute is not None:
        document["by_attribute"] = by_attribute
    if by_attribute and any(by_attribute.values()):
        extra += ("\n" + format_attribute_table(by_attribute, summary) + "\n\nMean success AUC over the "
                  "sequences carrying each OTB attribute (their number in brackets).\n")
    from .results import write_atomic  # whole files or none: a reader never sees half a summary

    try:
        out.mkdir(parents=True, exist_ok=True)
        write_atomic(json_path, json.dumps(_finite_or_none(document), indent=2) + "\n")
        write_atomic(md_path, "# vidtrack evaluation\n\n" + format_table(summary) + "\n\n"
                           "AUC: OTB success AUC (mean over IoU thresholds 0, 0.05, ..., 1); Prec@20: fraction "
                           "of frames with centre error <= 20 px; PASCAL: fraction with IoU > 0.5; CLE: mean "
                           "centre-location error; fps: tracker frames per second, decoding excluded. Only "
                           "annotated ground-truth frames are scored.\n" + extra)
    except OSError as exc:
        raise OutputError(f"cannot write the summary in {out}: {exc.strerror or exc}") from None
    return json_path, md_path
