"""Readers of live inputs: a stream FFmpeg reads (through PyAV), a video piped on stdin, a camera (OpenCV).

A reader is opened once (:meth:`open`), which connects, checks that the
input is video and decodes its first frame, raising
:class:`~vidtrack.errors.SourceError` (one line, exit 2) when it cannot.
:meth:`frames` then yields :class:`~vidtrack.types.Frame` values numbered by
a received-frame counter, each with its presentation time (``timestamp``).
The reader knows nothing of threads: :class:`~vidtrack.sources.live.LiveSource`
runs it in one.

A stream that stalls (no data for ``timeout`` seconds) or breaks with a
network error is reopened after each delay of ``reconnect_delays`` in turn;
when every attempt fails, :meth:`frames` raises :class:`StreamLost`, whose
message is the one line the command prints (exit 1).  A stream whose server
ends it (end of file) ends the frames normally.
"""

from __future__ import annotations

import threading
import time
from typing import Iterator

import numpy as np

from ..errors import SourceError
from ..types import Frame
from .files import TEXT_CODECS, TEXT_FORMATS

#: Seconds waited after a stalled or broken stream before each reconnect; their number is the reconnects tried.
RECONNECT_DELAYS = (0.5, 1.0, 2.0)

#: Seconds a stream may send no data before it counts as stalled (``--stream-timeout``).
DEFAULT_STREAM_TIMEOUT = 10.0

#: A frame rate outside this range is not believed (the source then reports 30 fps).
_PLAUSIBLE_FPS = (1.0, 240.0)


class StreamLost(Exception):
    """A live input that stopped part-way and could not be reopened; ``str()`` is the one line to print."""


def _plausible_fps(rate: float | None) -> float:
    rate = float(rate or 0.0)
    return rate if _PLAUSIBLE_FPS[0] <= rate <= _PLAUSIBLE_FPS[1] else 30.0


def _reason(exc: BaseException) -> str:
    """A short reason from a PyAV or OS error (``Connection refused``), without errno or URL."""
    import av

    if isinstance(exc, av.ExitError):
        return "no answer"
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return str(text).rstrip(".")


def _delays_text(delays: tuple[float, ...]) -> str:
    return ", ".join(f"{delay:g}" for delay in delays) + " s"


class PyAVStream:
    """Frames of any input FFmpeg opens: ``rtsp://``, ``rtmp://``, ``http(s)://`` (MJPEG too), ``tcp://``,
    ``udp://``, ``srt://`` ... or ``pipe:0`` (stdin).

    Parameters
    ----------
    url
        What FFmpeg opens.
    label
        How messages name the input (default: ``stream URL``).
    timeout
        Seconds the connection and each read may wait (PyAV's
        ``av.open(url, timeout=(open, read))``); None waits for ever (stdin,
        whose writer sets the pace).
    reconnect_delays
        Seconds waited before each reconnect after a stall or an error;
        empty: no reconnect (stdin cannot be reopened).
    """

    def __init__(self, url: str, *, label: str | None = None, timeout: float | None = DEFAULT_STREAM_TIMEOUT,
                 reconnect_delays: tuple[float, ...] = RECONNECT_DELAYS) -> None:
        self.url = url
        self.label = label or f"stream {url}"
        self.timeout = timeout
        self.reconnect_delays = tuple(reconnect_delays)
        self.fps = 30.0
        self.on_warning = None
        self.stop_event = threading.Event()
        self._container = None
        self._decoded: Iterator | None = None
        self._first: Frame | None = None
        self._received = 0
        self._clock_start: float | None = None

    # -- opening ---------------------------------------------------------------------------------------

    def _connect(self):
        """Open the container and check that it holds video; the decoded frames' iterator."""
        import av

        timeout = None if self.timeout is None else (self.timeout, self.timeout)
        container = av.open(self.url, timeout=timeout, metadata_errors="ignore")
        try:
            format_names = set(container.format.name.split(","))
            streams = list(container.streams.video)
            if format_names & TEXT_FORMATS or {s.codec_context.name for s in streams} & TEXT_CODECS:
                raise SourceError(f"not a video: {self.label} (it is text)")
            if not streams:
                raise SourceError(f"not a video: {self.label} (no video stream in its "
                                  f"{container.format.name} data)")
            stream = streams[0]
            stream.thread_type = "SLICE"   # frame threads would hold back one frame each: latency
            self.fps = _plausible_fps(stream.average_rate or stream.guessed_rate)
        except BaseException:
            container.close()
            raise
        self._container = container
        return _decode(container, stream)

    def open(self) -> None:
        """Connect, check the input is video and decode its first frame.

        Raises
        ------
        SourceError
            When it cannot be reached, is not video, or sends no frame.
        """
        import av

        try:
            self._decoded = self._connect()
            first = next(self._decoded, None)
        except SourceError:
            raise
        except (av.FFmpegError, OSError, ValueError) as exc:
            self.close()
            reason = (f"no answer within {self.timeout:g} s" if isinstance(exc, av.ExitError) and self.timeout
                      else _reason(exc))
            raise SourceError(f"cannot open {self.label}: {reason}") from None
        if first is None:
            self.close()
            raise SourceError(f"{self.label} holds no decodable video frame")
        self._first = self._frame(first)

    # -- reading ---------------------------------------------------------------------------------------

    def _frame(self, frame) -> Frame:
        """A PyAV frame -> :class:`Frame` numbered by the received counter, stamped by the stream's clock."""
        image = frame.to_ndarray(format="bgr24")
        timestamp = frame.time
        if timestamp is None:   # a stream without presentation times (some MJPEG): seconds since the first frame
            now = time.monotonic()
            self._clock_start = now if self._clock_start is None else self._clock_start
            timestamp = now - self._clock_start
        result = Frame(self._received, np.ascontiguousarray(image), timestamp=float(timestamp))
        self._received += 1
        return result

    def _reconnect(self, reason: str) -> bool:
        """Reopen after each delay in turn: True once connected, False when every attempt failed (or stopped)."""
        import av

        self.close()
        for attempt, delay in enumerate(self.reconnect_delays, 1):
            if self.stop_event.wait(delay):
                return False
            try:
                self._decoded = self._connect()
            except (SourceError, av.FFmpegError, OSError, ValueError):
                continue
            if self.on_warning is not None:
                self.on_warning(f"{self.label} {reason} at frame {self._received}; "
                                f"reconnected (attempt {attempt} of {len(self.reconnect_delays)})")
            return True
        return False

    def frames(self) -> Iterator[Frame]:
        """The first frame, then every frame decoded until the stream ends.

        Raises
        ------
        StreamLost
            When the stream stalls or breaks and no reconnect succeeds.
        """
        import av

        if self._first is None:
            raise RuntimeError("open() the stream first")
        yield self._first
        while True:
            try:
                for frame in self._decoded:
                    yield self._frame(frame)
                return   # the server ended the stream
            except av.ExitError:
                reason = f"stalled (no data for {self.timeout:g} s)"
            except (av.FFmpegError, OSError) as exc:
                reason = f"broke ({_reason(exc)})"
            if self.stop_event.is_set():
                return
            if not self._reconnect(reason):
                if self.stop_event.is_set():
                    return
                tries = (f"{len(self.reconnect_delays)} reconnects failed "
                         f"(after {_delays_text(self.reconnect_delays)})" if self.reconnect_delays
                         else "it cannot be reopened")
                raise StreamLost(f"{self.label} {reason} at frame {self._received}; {tries}")

    def close(self) -> None:
        """Close the connection (the reader's own thread calls it)."""
        container, self._container, self._decoded = self._container, None, None
        if container is not None:
            try:
                container.close()
            except Exception:   # closing a broken connection: nothing left to save
                pass


def _decode(container, stream) -> Iterator:
    """Decoded frames of ``stream``; a packet that does not decode (corrupt data) is passed over."""
    import av

    for packet in container.demux(stream):
        try:
            frames = packet.decode()
        except av.InvalidDataError:
            continue
        yield from frames


class CameraStream:
    """Frames of a camera by its index (``cv2.VideoCapture(index)``).

    A camera that stops sending frames is reopened after each delay of
    ``reconnect_delays``; then :meth:`frames` raises :class:`StreamLost`.
    """

    def __init__(self, index: int, *, timeout: float = DEFAULT_STREAM_TIMEOUT,
                 reconnect_delays: tuple[float, ...] = RECONNECT_DELAYS) -> None:
        self.index = int(index)
        self.label = f"camera {self.index}"
        self.timeout = timeout
        self.reconnect_delays = tuple(reconnect_delays)
        self.fps = 30.0
        self.on_warning = None
        self.stop_event = threading.Event()
        self._capture = None
        self._first: Frame | None = None
        self._received = 0
        self._clock_start: float | None = None

    def _connect(self) -> bool:
        import cv2

        milliseconds = int(self.timeout * 1000)
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)   # no backend warnings on stderr
        try:
            capture = cv2.VideoCapture(self.index, cv2.CAP_ANY, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, milliseconds,
                                                                 cv2.CAP_PROP_READ_TIMEOUT_MSEC, milliseconds])
        finally:
            cv2.utils.logging.setLogLevel(level)
        if not capture.isOpened():
            capture.release()
            return False
        self._capture = capture
        self.fps = _plausible_fps(capture.get(cv2.CAP_PROP_FPS))
        return True

    def _read(self) -> Frame | None:
        import cv2

        from .files import _as_bgr

        ok, image = self._capture.read()
        if not ok or image is None:
            return None
        now = time.monotonic()
        self._clock_start = now if self._clock_start is None else self._clock_start
        milliseconds = self._capture.get(cv2.CAP_PROP_POS_MSEC)
        timestamp = milliseconds / 1000.0 if milliseconds and milliseconds > 0 else now - self._clock_start
        frame = Frame(self._received, _as_bgr(image), timestamp=float(timestamp))
        self._received += 1
        return frame

    def open(self) -> None:
        """Open the camera and read its first frame.

        Raises
        ------
        SourceError
            When there is no camera at the index, or it sends no frame.
        """
        if not self._connect():
            raise SourceError(f"no camera at index {self.index} (cannot open it)")
        self._first = self._read()
        if self._first is None:
            self.close()
            raise SourceError(f"camera {self.index} opens but sends no frame")

    def frames(self) -> Iterator[Frame]:
        """The first frame, then every frame the camera sends; :class:`StreamLost` when it stops for good."""
        if self._first is None:
            raise RuntimeError("open() the camera first")
        yield self._first
        while not self.stop_event.is_set():
            frame = self._read()
            if frame is not None:
                yield frame
                continue
            self.close()
            for attempt, delay in enumerate(self.reconnect_delays, 1):
                if self.stop_event.wait(delay):
                    return
                if self._connect():
                    if self.on_warning is not None:
                        self.on_warning(f"{self.label} stopped at frame {self._received}; reconnected "
                                        f"(attempt {attempt} of {len(self.reconnect_delays)})")
                    break
            else:
                raise StreamLost(f"{self.label} stopped sending frames at frame {self._received}; "
                                 f"{len(self.reconnect_delays)} reconnects failed "
                                 f"(after {_delays_text(self.reconnect_delays)})")

    def close(self) -> None:
        capture, self._capture = self._capture, None
        if capture is not None:
            capture.release()
