"""Text sinks: the boxes file and the per-frame CSV log, flushed frame by frame."""

from __future__ import annotations

from pathlib import Path

from ..types import Frame, TrackState
from .base import open_text_output


def format_box(box, decimals: int = 2) -> str:
    """``x,y,w,h`` with trailing zeros trimmed (``56,20,31,45`` or ``56.25,...``)."""
    return ",".join(f"{v:.{decimals}f}".rstrip("0").rstrip(".") for v in box.as_array())


class BoxesSink:
    """One ``x,y,w,h`` line per frame (0-based pixels); line 1 is the init box."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open_text_output(self.path)

    def write(self, frame: Frame, state: TrackState) -> None:
        self._file.write(format_box(state.box) + "\n")

    def close(self) -> None:
        self._file.close()


class CsvLogSink:
    """``frame,x,y,w,h,confidence,status`` per frame, with a header."""

    HEADER = "frame,x,y,w,h,confidence,status\n"

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open_text_output(self.path)
        self._file.write(self.HEADER)

    def write(self, frame: Frame, state: TrackState) -> None:
        self._file.write(f"{state.index},{format_box(state.box)},{state.confidence:.4f},{state.status}\n")

    def close(self) -> None:
        self._file.close()
