"""Text sinks: the boxes file and the per-frame CSV log, written line by line.

Each line goes to the operating system whole (:class:`~vidtrack.sinks.base.LineFile`):
after a hard stop or a full disk the files end with their last complete line.
"""

from __future__ import annotations

from pathlib import Path

from ..types import Frame, TrackState
from .base import LineFile


def format_box(box, decimals: int = 2) -> str:
    """``x,y,w,h`` with trailing zeros trimmed (``56,20,31,45`` or ``56.25,...``)."""
    return ",".join(f"{v:.{decimals}f}".rstrip("0").rstrip(".") for v in box.as_array())


class BoxesSink:
    """One ``x,y,w,h`` line per frame (0-based pixels); line 1 is the init box."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)

    def write(self, frame: Frame, state: TrackState) -> None:
        self._file.write_line(format_box(state.box))

    def close(self) -> None:
        self._file.close()


class CsvLogSink:
    """``frame,x,y,w,h,confidence,status`` per frame, with a header."""

    HEADER = "frame,x,y,w,h,confidence,status\n"

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)
        self._file.write_line(self.HEADER.rstrip("\n"))

    def write(self, frame: Frame, state: TrackState) -> None:
        self._file.write_line(f"{state.index},{format_box(state.box)},{state.confidence:.4f},{state.status}")

    def close(self) -> None:
        self._file.close()
