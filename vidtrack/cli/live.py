"""Live inputs on ``vidtrack``'s command line: the input argument, ``--realtime``, ``--stream-timeout``, the summary.

:mod:`vidtrack.cli.track` calls these helpers; the sources themselves are in
:mod:`vidtrack.sources` (:func:`~vidtrack.sources.open_input`).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from ..errors import UsageError

#: Help of the input argument.
INPUT_HELP = ("video file (mp4, avi, webm ...), folder of frame images, camera index (0), stream URL "
              "(rtsp://, rtmp://, http(s):// including MJPEG, tcp://, udp://, srt:// ...) or - for a video on stdin")


def add_live_arguments(parser: argparse.ArgumentParser) -> None:
    """``--realtime`` and ``--stream-timeout``."""
    from ..sources import DEFAULT_STREAM_TIMEOUT, RECONNECT_DELAYS

    group = parser.add_argument_group(
        "live inputs", "cameras and streams are read live: the tracker takes the newest frame and drops the ones "
                       "it cannot keep up with")
    group.add_argument("--realtime", action="store_true",
                       help="read a file live too, at its own frame rate (and stdin without holding its writer back)")
    group.add_argument("--stream-timeout", type=float, default=DEFAULT_STREAM_TIMEOUT, metavar="SECONDS",
                       help=f"a stream or camera that sends nothing this long (default {DEFAULT_STREAM_TIMEOUT:g}) "
                            f"is reopened {len(RECONNECT_DELAYS)} times, after "
                            f"{', '.join(f'{d:g}' for d in RECONNECT_DELAYS)} s; then the run ends with exit 1")


def open_frames(args: argparse.Namespace):
    """The source of ``args.video`` (:func:`vidtrack.sources.open_input`), warnings of a live one on stderr.

    Raises
    ------
    UsageError
        For a ``--stream-timeout`` that is not a positive number.
    SourceError
        When the input cannot be opened (one line, exit 2).
    """
    from ..sources import open_input
    from .common import say

    if not (math.isfinite(args.stream_timeout) and args.stream_timeout > 0):
        raise UsageError(f"--stream-timeout must be a positive number of seconds, got {args.stream_timeout:g}")
    source = open_input(args.video, realtime=args.realtime, stream_timeout=args.stream_timeout)
    if is_live(source):
        source.on_warning = lambda message: say(f"warning: {message}")
        source.limit = args.max_frames
    return source


def is_live(source) -> bool:
    """True for a source read through a reader thread (counts frames received and dropped)."""
    return hasattr(source, "received") and hasattr(source, "dropped")


class LatencyStats:
    """Latency from a frame's arrival to its result, kept in a fixed histogram so memory stays flat.

    Bins are logarithmic, :data:`BINS_PER_DECADE` per decade from 10 µs to
    1000 s, so a quantile is known to within about 1 %; :meth:`quantile`
    returns the geometric centre of the bin holding it.
    """

    BINS_PER_DECADE = 200
    LOW, HIGH = 1e-5, 1e3

    def __init__(self) -> None:
        decades = math.log10(self.HIGH / self.LOW)
        self.edges = self.LOW * 10.0 ** (np.arange(int(decades * self.BINS_PER_DECADE) + 1) / self.BINS_PER_DECADE)
        self.counts = np.zeros(len(self.edges) + 1, dtype=np.int64)   # below LOW, the bins, above HIGH
        self.count = 0

    def add(self, seconds: float) -> None:
        """Record one latency in seconds."""
        self.counts[int(np.searchsorted(self.edges, seconds, side="right"))] += 1
        self.count += 1

    def quantile(self, q: float) -> float:
        """The ``q`` quantile (0..1) in seconds; nan before any latency is recorded."""
        if self.count == 0:
            return float("nan")
        rank = min(max(math.ceil(q * self.count), 1), self.count)   # the nearest-rank quantile
        slot = int(np.searchsorted(np.cumsum(self.counts), rank))
        if slot == 0:
            return self.LOW
        if slot >= len(self.edges):
            return self.HIGH
        return float(math.sqrt(self.edges[slot - 1] * self.edges[slot]))


class LiveMonitor:
    """Latency of every tracked frame of a live source, from its arrival to the result.

    ``on_state(state)`` is the run's per-frame callback (it finds the
    frame's arrival by ``source.arrival(state.index)``); a callback given the
    frame itself calls ``record(frame.arrival)``.  ``line(tracked)`` is the summary.
    The first frame is not counted: it waits for the outputs to open and the
    tracker to initialise on the init box, which is start-up, not tracking.
    """

    def __init__(self, source) -> None:
        import time

        self.source = source
        self.latency = LatencyStats()
        self._clock = time.monotonic
        self._started = False

    def on_state(self, state) -> None:
        """Record the latency of the frame ``state`` belongs to (called once its outputs are written)."""
        self.record(self.source.arrival(state.index) if is_live(self.source) else None)

    def record(self, arrival: float | None) -> None:
        """Record the latency of a frame that arrived at ``arrival`` (``Frame.arrival``; None: not live), now."""
        if arrival is not None and self._started:
            self.latency.add(self._clock() - arrival)
        self._started = True

    def line(self, tracked: int) -> str:
        """``live: received R, tracked T, dropped D; latency ... median M ms, 95th percentile P ms``."""
        source = self.source
        text = f"live: received {source.received}, tracked {tracked}, dropped {source.dropped}"
        if self.latency.count:
            text += (f"; latency from arrival to result median {1000 * self.latency.quantile(0.5):.1f} ms, "
                     f"95th percentile {1000 * self.latency.quantile(0.95):.1f} ms")
        return text


def stream_failure(source) -> str | None:
    """Why a live source stopped part-way (its one line, exit 1), None when it ended normally."""
    return getattr(source, "stream_error", None)


def close_source(source) -> None:
    """Stop a live source's reader thread (nothing for a file source)."""
    close = getattr(source, "close", None)
    if close is not None:
        close()
