"""The papers' values beside vidtrack's: relative differences, table cells and claims.

Every ``vidtrack reproduce`` table prints, beside each figure vidtrack
computes, the value the paper reports (typed from the paper's table: the
*target*, labelled as the paper's, never used as a result) and the relative
difference ``(vidtrack - paper) / paper``.  The JSON of every experiment
carries the same comparison as a flat list under ``"vs_paper"``::

    {"table": "Table 1", "row": "SVK", "column": "whole",
     "vidtrack": 23.68, "paper": 22.41, "rel_diff": 0.057}

and its claims under ``"claims"``: ``{"claim": str, "holds": bool, "detail": str}``
(the report of ``vidtrack reproduce all`` opens with them).
"""

from __future__ import annotations

import math


def relative_difference(ours: float, paper: float | None) -> float | None:
    """``(ours - paper) / |paper|``; None when there is no paper value (or it is 0)."""
    if paper is None or paper == 0 or ours is None or not math.isfinite(ours):
        return None
    return (ours - paper) / abs(paper)


def comparison(table: str, row: str, column: str, ours: float, paper: float | None) -> dict:
    """One ``vs_paper`` entry."""
    return {"table": table, "row": row, "column": column, "vidtrack": float(ours),
            "paper": None if paper is None else float(paper),
            "rel_diff": relative_difference(float(ours), paper)}


def cell(ours: float, paper: float | None, width: int = 22, digits: int = 2) -> str:
    """``"23.68 (22.41, +5.7%)"`` right-aligned in ``width``; ``"23.68 (-)"`` without a paper value."""
    d = relative_difference(ours, paper)
    text = (f"{ours:.{digits}f} ({paper:.{digits}f}, {100 * d:+.1f}%)" if d is not None
            else f"{ours:.{digits}f} (-)")
    return f"{text:>{width}}"


def claim(text: str, holds: bool, detail: str) -> dict:
    """One ``claims`` entry."""
    return {"claim": text, "holds": bool(holds), "detail": detail}


LEGEND = "cells: vidtrack (paper, relative difference)"
