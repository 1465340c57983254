"""Live mode: a reader thread that keeps only the newest frame, so the tracker never falls behind a queue.

:class:`LiveSource` runs a reader (:mod:`vidtrack.sources.streams`, or
:class:`FileClock` for ``--realtime`` on a file) in a background thread.  The
thread stamps each frame with its arrival (``Frame.arrival``,
:func:`time.monotonic`) and puts it in a one-slot mailbox; a frame still in
the slot when a newer one arrives is dropped (counted in ``dropped``).  The
tracker takes whatever the slot holds, so it always works on the newest frame
and no queue grows however slow it is: a frame waits at most for the frame
being tracked when it arrived.  The first frame is kept till the tracker takes
it (the init box is drawn on it).  Frame indices are the reader's counter, so
dropped frames leave gaps in them.

With ``drop=False`` the thread waits for the slot to empty instead: every
frame is tracked (stdin without ``--realtime``, whose writer is held back by
the pipe).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from dataclasses import replace
from typing import Iterator, Protocol

from ..errors import SourceError
from ..types import Frame
from .streams import StreamLost

#: Arrival times remembered for frames handed to the tracker, for :meth:`LiveSource.arrival` (oldest dropped).
_ARRIVALS_KEPT = 256


class Reader(Protocol):
    """What :class:`LiveSource` runs: ``open()``, ``frames()``, ``close()``, ``fps``, ``stop_event``, ``on_warning``."""

    fps: float
    stop_event: threading.Event
    on_warning: object

    def open(self) -> None: ...

    def frames(self) -> Iterator[Frame]: ...

    def close(self) -> None: ...


class FileClock:
    """A file source's frames released at the file's own frame rate from a clock (``--realtime`` on a file).

    Frame ``k`` is released ``(k - first) / fps`` seconds after the first
    frame, or as soon as it decodes when decoding is slower than that.  The
    file source's own record of undecodable frames (``missing``,
    ``skipped``, ``decode_error``, ``on_skip``) is that of this reader.
    """

    def __init__(self, source) -> None:
        self.source = source
        self.fps = float(source.fps)
        self.label = str(getattr(source, "path", "video"))
        self.stop_event = threading.Event()
        self.on_warning = None
        self._frames: Iterator[Frame] | None = None
        self._first: Frame | None = None

    def open(self) -> None:
        """Decode the first frame (a file that has none raises :class:`SourceError`)."""
        self._frames = iter(self.source)
        self._first = next(self._frames, None)
        if self._first is None:
            raise SourceError(f"no frame to track in {self.label}")

    def frames(self) -> Iterator[Frame]:
        start, first = time.monotonic(), self._first.index
        yield self._first
        for frame in self._frames:
            wait = start + (frame.index - first) / self.fps - time.monotonic()
            if wait > 0 and self.stop_event.wait(wait):
                return
            yield frame

    def close(self) -> None:
        close = getattr(self._frames, "close", None)
        if close is not None:
            close()


class LiveSource:
    """Frames of ``reader`` through a one-slot mailbox filled by a background thread.

    Parameters
    ----------
    reader
        A :class:`Reader`; opened here, so an input that cannot be read
        raises :class:`SourceError` before anything else starts.
    drop
        True (live): a newer frame replaces the one waiting, which is
        dropped.  False: the reader waits till the tracker takes it.

    Attributes
    ----------
    received, dropped, taken
        Frames the reader delivered, that were replaced before the tracker
        took them, and that the tracker took.
    stream_error
        The one line saying why the input stopped part-way (:class:`StreamLost`),
        None when it ended normally.
    limit
        Frames to hand out at most (None: all), so a run of ``--max-frames N``
        never waits for frame N + 1.
    on_warning
        Called from the reader's thread with a message (a reconnect that succeeded).
    """

    def __init__(self, reader: Reader, *, drop: bool = True) -> None:
        self.reader = reader
        self.drop = drop
        reader.open()
        self.fps = float(reader.fps)
        self.received = self.dropped = self.taken = 0
        self.stream_error: str | None = None
        self.limit: int | None = None
        self._failure: BaseException | None = None
        self._first: Frame | None = None
        self._slot: Frame | None = None
        self._done = False
        self._condition = threading.Condition()
        self._arrivals: OrderedDict[int, float] = OrderedDict()
        self._thread = threading.Thread(target=self._read, name="vidtrack-reader", daemon=True)
        self._thread.start()

    # -- what a file source offers, passed through (FileClock) ----------------------------------------------

    def __len__(self) -> int:
        return 0   # unknown: frames are dropped, or the input has no end

    @property
    def decode_error(self) -> str | None:
        return getattr(getattr(self.reader, "source", None), "decode_error", None)

    @property
    def skipped(self) -> list:
        return list(getattr(getattr(self.reader, "source", None), "skipped", ()))

    @property
    def missing(self) -> set[int]:
        return getattr(getattr(self.reader, "source", None), "missing", set())

    @property
    def on_skip(self):
        return getattr(getattr(self.reader, "source", None), "on_skip", None)

    @on_skip.setter
    def on_skip(self, callback) -> None:
        source = getattr(self.reader, "source", None)
        if source is not None:
            source.on_skip = callback

    @property
    def on_warning(self):
        return self.reader.on_warning

    @on_warning.setter
    def on_warning(self, callback) -> None:
        self.reader.on_warning = callback

    # -- the reader's thread -------------------------------------------------------------------------------

    def _put(self, frame: Frame) -> bool:
        """Put ``frame`` in the mailbox (the first frame apart); False once the source is closed."""
        with self._condition:
            while not self.drop and (self._slot is not None or self._first is not None):
                if self.reader.stop_event.is_set():
                    return False
                self._condition.wait(0.2)
            if self.reader.stop_event.is_set():
                return False
            self.received += 1
            if self.received == 1:
                self._first = frame
            else:
                self.dropped += self._slot is not None
                self._slot = frame
            self._condition.notify_all()
        return True

    def _read(self) -> None:
        try:
            for frame in self.reader.frames():
                if not self._put(replace(frame, arrival=time.monotonic())):
                    break
        except StreamLost as exc:
            self.stream_error = str(exc)
        except BaseException as exc:   # an error in reading itself: raised again in the tracker's thread
            self._failure = exc
        finally:
            try:
                self.reader.close()
            finally:
                with self._condition:
                    self._done = True
                    self._condition.notify_all()

    # -- the tracker's side --------------------------------------------------------------------------------

    def _take(self) -> Frame | None:
        if self.limit is not None and self.taken >= self.limit:
            return None
        with self._condition:
            while self._first is None and self._slot is None and not self._done:
                self._condition.wait(0.5)
            if self._first is not None:
                frame, self._first = self._first, None
            elif self._slot is not None:
                frame, self._slot = self._slot, None
            else:
                return None
            self._condition.notify_all()
        self.taken += 1
        self._arrivals[frame.index] = frame.arrival
        while len(self._arrivals) > _ARRIVALS_KEPT:
            self._arrivals.popitem(last=False)
        return frame

    def __iter__(self) -> Iterator[Frame]:
        try:
            while True:
                frame = self._take()
                if frame is None:
                    break
                yield frame
            if self._failure is not None:
                raise self._failure
        finally:
            self.close()

    def arrival(self, index: int) -> float | None:
        """The :func:`time.monotonic` arrival of the frame ``index`` handed out lately (None if unknown)."""
        return self._arrivals.get(index)

    def close(self, wait: float = 1.0) -> None:
        """Stop the reader's thread (waiting at most ``wait`` seconds: a blocked read ends by its own timeout)."""
        self.reader.stop_event.set()
        with self._condition:
            self._condition.notify_all()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(wait)
