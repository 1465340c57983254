"""A file that a library writes through a pipe, so that this process sees (and survives) its write errors.

Rerun's file writer runs on a thread of its own: on a full disk it stops, and
flushing or closing the recording can then wait forever.  Given
:attr:`RelayedFile.inlet` (a pipe) instead of the file, the library never
meets the disk: a thread here copies the pipe into the file, keeps the first
write error, and goes on draining the pipe, so the library never blocks.
After each flush of the library, :meth:`RelayedFile.sync` marks the file's
size as complete or raises the error; :meth:`RelayedFile.close` cuts the file
back to its last complete size when a write failed.
"""

from __future__ import annotations

import array
import fcntl
import os
import select
import termios
import threading
import time
from pathlib import Path

from .base import failed_write


def _pending(fd: int) -> int:
    """Bytes waiting in the pipe ``fd``."""
    count = array.array("i", [0])
    fcntl.ioctl(fd, termios.FIONREAD, count, True)
    return int(count[0])


def relay_supported() -> bool:
    """Whether this system names a process's open pipes as files (``/dev/fd/N``: Linux, macOS)."""
    return os.path.isdir("/dev/fd")


class RelayedFile:
    """``path``, written by whoever writes :attr:`inlet` (a ``/dev/fd/N`` pipe path), through a thread here.

    Parameters
    ----------
    path
        The file to write (created or truncated now).

    Raises
    ------
    OSError
        When ``path`` cannot be created.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open(self.path, "wb")
        self._read, self._write = os.pipe()
        self.inlet = f"/dev/fd/{self._write}"
        self.error: OSError | None = None
        self._written = 0       # bytes in the file
        self._complete = 0      # bytes in the file at the last sync
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._pump, name=f"relay {self.path.name}", daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        while True:
            readable = select.select([self._read], [], [], 0.1)[0]
            if not readable:
                continue
            with self._lock:   # read and write under the lock: sync() sees no byte in between
                data = os.read(self._read, 1 << 16)
                if not data:
                    return   # every writer closed the pipe
                if self.error is None:
                    try:
                        self._file.write(data)
                        self._file.flush()
                        self._written += len(data)
                    except OSError as exc:
                        self.error = exc   # keep draining: the writer on the other side never blocks

    def sync(self) -> None:
        """After the writer flushed into :attr:`inlet`: wait till the file holds it all, and mark that size complete.

        Raises
        ------
        OutputError
            :class:`~vidtrack.sinks.base.WriteFailed` for a full disk (and
            the like) when a write to the file failed.
        """
        while True:
            with self._lock:
                if self.error is not None:
                    raise failed_write(self.path, self.error)
                if _pending(self._read) == 0:
                    self._complete = self._written
                    return
            time.sleep(0.001)

    def close(self) -> None:
        """Once the writer closed :attr:`inlet`: copy what is left, close the file; after a failed write, cut it
        back to its last complete size and raise that failure (see :meth:`sync`)."""
        if self._write < 0:
            return
        os.close(self._write)
        self._write = -1
        self._thread.join()
        os.close(self._read)
        try:
            self._file.close()
        except OSError as exc:
            self.error = self.error or exc
        if self.error is not None:
            try:
                os.truncate(self.path, self._complete)
            except OSError:
                pass
            raise failed_write(self.path, self.error)
