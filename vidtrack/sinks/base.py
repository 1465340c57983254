"""The sink protocol and opening output files with clear errors."""

from __future__ import annotations

from pathlib import Path
from typing import IO, Protocol, runtime_checkable

from ..errors import OutputError
from ..types import Frame, TrackState


@runtime_checkable
class Sink(Protocol):
    """Receives every frame's :class:`TrackState`; writes incrementally.

    ``write`` is called once per frame, in order, the first call with the
    init state; ``close`` finishes the output (also after an interruption).
    """

    def write(self, frame: Frame, state: TrackState) -> None: ...

    def close(self) -> None: ...


def open_text_output(path: str | Path) -> IO[str]:
    """Open ``path`` for writing text, line-buffered; missing parent folders are created.

    Raises
    ------
    OutputError
        When the file cannot be created (folder not writable, path is a folder ...).
    """
    path = Path(path)
    try:
        if path.is_dir():
            raise OutputError(f"cannot write {path}: it is a folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        return open(path, "w", buffering=1, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def close_and_remove(sinks) -> None:
    """Close ``sinks`` and delete the files they created (outputs of a run that wrote no frame)."""
    for sink in sinks:
        sink.close()
        path = getattr(sink, "path", None)
        if path is not None and Path(path).is_file():
            Path(path).unlink(missing_ok=True)
