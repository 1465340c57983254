"""Each frame's tracking time in an evaluation job.

GOT-10k's submission format (and the got10k toolkit's speed figures) wants
the tracker's seconds for every frame, the first (initialising) frame
included: ``<seq>_time.txt``, one line per frame.  :class:`FrameTimer` wraps
the tracker a job runs and keeps them; the job's run record stores them
(``frame_seconds``) and :mod:`vidtrack.eval.toolkit` writes them.
"""

from __future__ import annotations

import time
from typing import Any

#: Significant digits kept of each frame's time in a run record.
DIGITS = 6


class FrameTimer:
    """A tracker (:class:`~vidtrack.tracker.Tracker`) that keeps the seconds each frame's ``initialize``/``step`` took.

    Every other attribute is the wrapped tracker's.  ``seconds`` maps a
    frame's index to its time; a frame the source could not decode (the
    filter predicted through it without calling ``step``) has none.
    """

    def __init__(self, tracker: Any) -> None:
        self.tracker = tracker
        self.seconds: dict[int, float] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.tracker, name)

    def initialize(self, frame, box):
        start = time.perf_counter()
        state = self.tracker.initialize(frame, box)
        self.seconds[frame.index] = time.perf_counter() - start
        return state

    def step(self, frame):
        start = time.perf_counter()
        state = self.tracker.step(frame)
        self.seconds[frame.index] = time.perf_counter() - start
        return state

    def per_frame(self, frames: int) -> list[float]:
        """Seconds of frames ``0 .. frames - 1`` in order (0 for a frame without a time), rounded to
        :data:`DIGITS` significant digits."""
        return [float(f"{self.seconds.get(index, 0.0):.{DIGITS}g}") for index in range(frames)]
