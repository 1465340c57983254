"""Text sinks: the boxes file and the per-frame CSV log, written line by line.

Each line goes to the operating system whole (:class:`~vidtrack.sinks.base.LineFile`):
after a hard stop or a full disk the files end with their last complete line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

from ..types import Frame, TrackState
from .base import LineFile


def format_box(box, decimals: int = 2) -> str:
    """``x,y,w,h`` with trailing zeros trimmed (``56,20,31,45`` or ``56.25,...``)."""
    return ",".join(f"{v:.{decimals}f}".rstrip("0").rstrip(".") for v in box.as_array())


class BoxesSink:
    """The boxes file: one ``x,y,w,h`` line per frame with one target, MOT Challenge lines with several.

    One target: 0-based pixels, line 1 the init box.  Several targets: a line
    ``frame,id,x,y,w,h,confidence,-1,-1,-1`` per target and frame, frames
    1-based (the MOT Challenge convention; the box stays 0-based pixels),
    every target on every frame (also while lost: its predicted box, with its
    confidence).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)

    def write(self, frame: Frame, targets: Mapping[int, TrackState]) -> None:
        if len(targets) == 1:
            (state,) = targets.values()
            self._file.write_line(format_box(state.box))
            return
        for target, state in targets.items():
            self._file.write_line(mot_line(frame.index + 1, target, state))

    def close(self) -> None:
        self._file.close()


def mot_line(frame_number: int, target: int, state: TrackState) -> str:
    """``frame,id,x,y,w,h,confidence,-1,-1,-1``: one MOT Challenge result line (``frame_number`` 1-based)."""
    return f"{frame_number},{target},{format_box(state.box)},{state.confidence:.4f},-1,-1,-1"


class CsvLogSink:
    """``frame,id,timestamp,x,y,w,h,confidence,status`` per target and frame, with a header.

    ``timestamp`` is the frame's presentation time in seconds (6 decimals),
    empty when the source has none (a frame folder).
    """

    HEADER = "frame,id,timestamp,x,y,w,h,confidence,status\n"

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)
        self._file.write_line(self.HEADER.rstrip("\n"))

    def write(self, frame: Frame, targets: Mapping[int, TrackState]) -> None:
        stamp = "" if frame.timestamp is None else f"{frame.timestamp:.6f}"
        for target, state in targets.items():
            self._file.write_line(f"{state.index},{target},{stamp},{format_box(state.box)},"
                                  f"{state.confidence:.4f},{state.status}")

    def close(self) -> None:
        self._file.close()
