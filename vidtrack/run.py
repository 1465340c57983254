"""Drive a tracker over a frame stream into sinks, timing the tracking alone."""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

from .api import VidtrackTracker, track_frames
from .errors import OutputError
from .sinks.base import Sink, close_and_remove, uninterrupted
from .tracker import Tracker, make_state
from .types import Box, Frame, TrackState


@dataclass
class RunResult:
    """What a run did.

    ``frames`` tracked (init frame included), ``lost_frames`` with status
    lost, ``track_seconds`` spent in the tracker (decoding and sinks
    excluded), ``interrupted`` by Ctrl-C or a stopping signal (``signum``
    its number), ``decode_error`` when the source stopped early,
    ``output_error`` when an output could not be written part-way (a full
    disk: the run stopped there, every output keeps the frames written
    before), ``skipped`` the source's frames that did not decode (the tracker
    predicted through them: :class:`~vidtrack.sources.SkippedFrame`),
    ``last_state`` the final state.
    """

    frames: int = 0
    lost_frames: int = 0
    track_seconds: float = 0.0
    interrupted: bool = False
    signum: int | None = None
    decode_error: str | None = None
    output_error: OutputError | None = None
    skipped: list = field(default_factory=list)
    last_state: TrackState | None = None

    @property
    def fps(self) -> float:
        """Tracker frames per second (decoding and writing excluded)."""
        return self.frames / self.track_seconds if self.track_seconds > 0 else float("nan")


class PredictingThroughGaps(VidtrackTracker):
    """A :class:`~vidtrack.api.VidtrackTracker` that only predicts on the frames its source could not decode.

    On a frame whose index is in the source's ``missing`` set the filter
    predicts and is updated with no measurement (``update(None)``, which
    every filter takes); the measurer neither looks at it nor learns from it.
    """

    def __init__(self, tracker: Tracker, source: object) -> None:
        super().__init__(tracker)
        self.source = source

    def step_frame(self, frame: Frame) -> TrackState:
        if frame.index not in getattr(self.source, "missing", ()):
            return super().step_frame(frame)
        start = time.perf_counter()
        prior = self.tracker.filter.predict()
        state = make_state(frame.index, prior, None, self.tracker.filter.update(None))
        self.seconds += time.perf_counter() - start
        return self._keep(frame, state)


def run_tracker(tracker: Tracker, frames: Iterable[Frame], init_box: Box, sinks: Sequence[Sink] = (), *,
                max_frames: int | None = None, on_state: Callable[[TrackState], None] | None = None,
                validate_box: Callable[[Frame, Box], None] | None = None) -> RunResult:
    """Track ``init_box`` through ``frames``, writing every state to ``sinks``.

    The sinks are always closed, also after an exception or Ctrl-C (a
    KeyboardInterrupt, also one a stopping signal raises with a ``signum``:
    swallowed and reported as ``interrupted``), so every frame already tracked
    is on disk.  ``validate_box(first_frame, box)`` may raise to reject the
    init box once the frame size is known.  The loop is the Python API's
    (:func:`vidtrack.api.track_frames`), so both give the same boxes.  When
    anything raises before the first frame is written, the sinks' files are
    removed: bad input leaves no empty output behind.  An output that fails
    part-way (:class:`~vidtrack.errors.OutputError`, a full disk) ends the
    run: ``output_error`` says why, every sink is closed.  A frame the source
    lists as ``missing`` (it did not decode) is predicted through
    (:class:`PredictingThroughGaps`), so every sink still gets one state per frame.
    """
    result = RunResult()
    runner = PredictingThroughGaps(tracker, frames)
    try:
        for frame, state in track_frames(runner, frames, init_box, max_frames=max_frames, validate_box=validate_box):
            result.track_seconds = runner.seconds
            with uninterrupted():   # a stopping signal waits till every sink holds the frame
                for sink in sinks:
                    sink.write(frame, state)
                result.frames += 1
                result.lost_frames += state.status == "lost"
                result.last_state = state
            if on_state is not None:
                on_state(state)
    except KeyboardInterrupt as exc:
        result.interrupted = True
        result.signum = int(getattr(exc, "signum", signal.SIGINT))
    except OutputError as exc:
        if result.frames == 0:
            close_and_remove(sinks, errors=False)
            raise
        result.output_error = exc   # part-way (a full disk): stop here, keep what is written
    except BaseException:
        if result.frames == 0:  # bad input found at the first frame: leave no empty output behind
            close_and_remove(sinks, errors=False)
        raise
    finally:
        for sink in sinks:
            try:
                sink.close()
            except OutputError as exc:   # closing can fail on a full disk too: the first failure is reported
                result.output_error = result.output_error or exc
    result.decode_error = getattr(frames, "decode_error", None)
    result.skipped = list(getattr(frames, "skipped", ()))
    return result
