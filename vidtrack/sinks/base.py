"""The sink protocol and opening output files with clear errors."""

from __future__ import annotations

import errno
import os
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator, Mapping, Protocol, runtime_checkable

from ..errors import OutputError
from ..types import Frame, TrackState


@runtime_checkable
class Sink(Protocol):
    """Receives every frame's target states; writes incrementally.

    ``write(frame, targets)`` is called once per frame, in order, the first
    call with the init states; ``targets`` maps each target ID (a positive
    int; a one-target run is target 1) to its :class:`TrackState`, IDs
    ascending.  ``close`` finishes the output (also after an interruption).
    """

    def write(self, frame: Frame, targets: Mapping[int, TrackState]) -> None: ...

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


#: errno values of a write that fails part-way through a run (the device, not the user's input).
WRITE_FAILURES = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


class WriteFailed(OutputError):
    """An output that could not be written part-way through a run (a full disk): exit 1, not bad input."""


def failed_write(path: str | Path, exc: OSError) -> OutputError:
    """The error of a write to ``path`` that raised ``exc``: :class:`WriteFailed` for a full disk and the
    like (:data:`WRITE_FAILURES`), else :class:`~vidtrack.errors.OutputError`."""
    kind = WriteFailed if exc.errno in WRITE_FAILURES else OutputError
    return kind(f"cannot write {path}: {exc.strerror or exc}")


class LineFile:
    """A text file written one whole line at a time, straight to the operating system.

    When a write fails (a full disk) the file is cut back to its last
    complete line, so it stays readable, and :class:`WriteFailed` (or
    :class:`~vidtrack.errors.OutputError`) is raised.

    Parameters
    ----------
    path
        The file; created (with missing parent folders) or emptied.

    Raises
    ------
    OutputError
        When the file cannot be created.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            if self.path.is_dir():
                raise OutputError(f"cannot write {self.path}: it is a folder")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from None
        self._size = 0

    def write_line(self, text: str) -> None:
        """Append ``text`` and a newline, all of it or (after a failure, raised) none of it."""
        if self._fd is None:
            raise OutputError(f"cannot write {self.path}: it is closed")
        data = (text + "\n").encode("utf-8")
        done = 0
        try:
            while done < len(data):
                done += os.write(self._fd, data[done:])
        except OSError as exc:
            os.ftruncate(self._fd, self._size)   # back to the last complete line
            raise failed_write(self.path, exc) from None
        self._size += done

    def close(self) -> None:
        """Close the file (safe to call twice)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)


def close_and_remove(sinks, *, errors: bool = True) -> None:
    """Close ``sinks`` and delete the files they created (outputs of a run that wrote no frame).

    With ``errors=False`` an OutputError of a sink's ``close`` is ignored
    (the run is failing already; its files are removed anyway).
    """
    for sink in sinks:
        try:
            sink.close()
        except OutputError:
            if errors:
                raise
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
