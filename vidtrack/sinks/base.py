"""The sink protocol and opening output files with clear errors."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator, Protocol, runtime_checkable

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


#: Nesting depth of :func:`uninterrupted` blocks and the interruption they hold back.
_WRITING = {"depth": 0, "pending": None}


@contextmanager
def uninterrupted() -> Iterator[None]:
    """Within the block a stopping signal's exception waits for the block's end (see :func:`defer_interrupt`).

    A run writes each frame to every sink inside such a block, so after
    Ctrl-C or SIGTERM all the outputs hold the same frames; an evaluation
    starts each job process inside one, so no job is left half-started.
    Python raises a signal's exception in the main thread only, so in any
    other thread the block changes nothing.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _WRITING["depth"] += 1
    try:
        yield
    finally:
        _WRITING["depth"] -= 1
    pending = _WRITING["pending"]
    if _WRITING["depth"] == 0 and pending is not None:
        _WRITING["pending"] = None
        raise pending


def defer_interrupt(exc: BaseException) -> bool:
    """Hold ``exc`` back till the end of the :func:`uninterrupted` block in progress.

    A signal handler calls it: True when a block is in progress (the
    exception is raised at its end), False when the handler should raise
    ``exc`` itself.
    """
    if _WRITING["depth"] == 0:
        return False
    _WRITING["pending"] = exc
    return True
