"""The init boxes of one or several targets: ``--init-box`` (repeatable) and ``--init-boxes FILE``.

``--init-box`` given N times gives targets 1 .. N in order; ``--init-boxes
FILE`` reads one ``id,x,y,w,h`` line per target (a positive int ID, each ID
once; blank lines and lines starting with ``#`` are skipped).  The two are
alternatives.  Every error is one line naming the option or the file's line.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Callable, Mapping

from ..errors import UsageError
from ..types import Box, split_numbers
from .common import parse_init_box


def add_init_box_arguments(parser: argparse.ArgumentParser) -> None:
    """``--init-box x,y,w,h`` (repeatable) or ``--init-boxes FILE``: exactly one of them is required."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--init-box", action="append", metavar="x,y,w,h",
                       help="an object's box in the first frame, 0-based pixels; repeat it for several "
                            "targets (IDs 1, 2, ... in order)")
    group.add_argument("--init-boxes", metavar="FILE",
                       help="several targets: one id,x,y,w,h line per target (a positive int ID each)")


def read_init_boxes(path: str | Path) -> dict[int, Box]:
    """Target ID -> box from a file of ``id,x,y,w,h`` lines (IDs ascending).

    Raises
    ------
    UsageError
        ``FILE line N: ...`` for a line that is not a positive int ID and a
        valid box, or an ID given twice; also for a missing, unreadable or
        empty file.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or ("not a text file" if isinstance(exc, UnicodeDecodeError)
                                                     else exc)
        raise UsageError(f"cannot read --init-boxes {path}: {reason}") from None
    boxes: dict[int, Box] = {}
    first_line: dict[int, int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"{path} line {number}"
        parts = split_numbers(line)
        if len(parts) != 5:
            raise UsageError(f"{where}: expected id,x,y,w,h, got {line.strip()[:60]!r}")
        try:
            target = int(parts[0])
        except ValueError:
            target = 0
        if target < 1:
            raise UsageError(f"{where}: the target ID must be a positive integer, got {parts[0][:20]!r}")
        if target in boxes:
            raise UsageError(f"{where}: target ID {target} is already on line {first_line[target]}")
        boxes[target] = parse_init_box(",".join(parts[1:]), option=where)
        first_line[target] = number
    if not boxes:
        raise UsageError(f"--init-boxes {path} holds no id,x,y,w,h line")
    return dict(sorted(boxes.items()))


def init_boxes(args: argparse.Namespace) -> tuple[dict[int, Box], dict[int, str]]:
    """The targets of ``args`` (ID -> box) and how each box was given (for messages).

    Raises
    ------
    UsageError
        For a malformed box or file (see :func:`read_init_boxes`).
    """
    if getattr(args, "init_boxes", None):
        boxes = read_init_boxes(args.init_boxes)
        return boxes, {i: f"target {i} of --init-boxes" for i in boxes}
    texts = args.init_box
    if len(texts) == 1:
        return {1: parse_init_box(texts[0])}, {1: "--init-box"}
    boxes = {i: parse_init_box(text, option=f"--init-box #{i}") for i, text in enumerate(texts, start=1)}
    return boxes, {i: f"--init-box #{i}" for i in boxes}


def boxes_in_frame(names: Mapping[int, str]) -> Callable:
    """``validate_boxes(frame, boxes)`` rejecting a box that lies mostly outside the first frame."""
    from ..api import check_inside

    def validate(frame, boxes: Mapping[int, Box]) -> None:
        for target, box in boxes.items():
            check_inside(box, frame.width, frame.height, what=names.get(target, f"target {target}"))

    return validate
