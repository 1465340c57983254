"""Drive one tracker per target over a frame stream into sinks, timing the tracking alone."""

from __future__ import annotations

import signal
from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping, Sequence

from .api import track_targets
from .errors import OutputError
from .sinks.base import Sink, close_and_remove, uninterrupted
from .targets import MultiTargetTracker
from .tracker import Tracker
from .types import Box, Frame, TrackState


@dataclass
class RunResult:
    """What a run did.

    ``frames`` tracked (init frame included), ``lost_frames`` the states
    with status lost (summed over the targets), ``track_seconds`` spent in the tracker (decoding and sinks
    excluded), ``interrupted`` by Ctrl-C or a stopping signal (``signum``
    its number), ``decode_error`` when the source stopped early,
    ``output_error`` when an output could not be written part-way (a full
    disk: the run stopped there, every output keeps the frames written
    before), ``skipped`` the source's frames that did not decode (the tracker
    predicted through them: :class:`~vidtrack.sources.SkippedFrame`),
    ``last_states`` every target's final state (ID -> state), ``last_state``
    the lowest ID's.
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
    last_states: dict[int, TrackState] = field(default_factory=dict)

    @property
    def fps(self) -> float:
        """Tracker frames per second (decoding and writing excluded)."""
        return self.frames / self.track_seconds if self.track_seconds > 0 else float("nan")


def run_targets(multi: MultiTargetTracker, frames: Iterable[Frame], init_boxes: Mapping[int, Box],
                sinks: Sequence[Sink] = (), *, max_frames: int | None = None,
                on_frame: Callable[[Frame, Mapping[int, TrackState]], None] | None = None,
                validate_boxes: Callable[[Frame, Mapping[int, Box]], None] | None = None) -> RunResult:
    """Track every target of ``init_boxes`` (ID -> box) through ``frames``, writing each frame to ``sinks``.

    Each sink's ``write(frame, targets)`` gets every target's state (ID ->
    :class:`~vidtrack.types.TrackState`, IDs ascending); then
    ``on_frame(frame, targets)`` is called.  The sinks are always closed, also
    after an exception or Ctrl-C (a KeyboardInterrupt, also one a stopping
    signal raises with a ``signum``: swallowed and reported as
    ``interrupted``), so every frame already tracked is on disk.
    ``validate_boxes(first_frame, boxes)`` may raise to reject the init boxes
    once the frame size is known.  The loop is the Python API's
    (:func:`vidtrack.api.track_targets`), so both give the same boxes.  When
    anything raises before the first frame is written, the sinks' files are
    removed: bad input leaves no empty output behind.  An output that fails
    part-way (:class:`~vidtrack.errors.OutputError`, a full disk) ends the
    run: ``output_error`` says why, every sink is closed.  A frame the source
    lists as ``missing`` (it did not decode) is predicted through by every
    target (:meth:`MultiTargetTracker.predict_only`), so every sink still gets
    one state per target and frame.  ``multi``'s worker threads are ended.
    """
    result = RunResult()
    try:
        for frame, states in track_targets(multi, frames, init_boxes, max_frames=max_frames,
                                           validate_boxes=validate_boxes):
            result.track_seconds = multi.seconds
            with uninterrupted():   # a stopping signal waits till every sink holds the frame
                for sink in sinks:
                    sink.write(frame, states)
                result.frames += 1
                result.lost_frames += sum(state.status == "lost" for state in states.values())
                result.last_states = states
                result.last_state = states[min(states)]
            if on_frame is not None:
                on_frame(frame, states)
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
        multi.close()
        for sink in sinks:
            try:
                sink.close()
            except OutputError as exc:   # closing can fail on a full disk too: the first failure is reported
                result.output_error = result.output_error or exc
    result.decode_error = getattr(frames, "decode_error", None)
    result.skipped = list(getattr(frames, "skipped", ()))
    return result


def run_tracker(tracker: Tracker, frames: Iterable[Frame], init_box: Box, sinks: Sequence[Sink] = (), *,
                max_frames: int | None = None,
                on_frame: Callable[[Frame, Mapping[int, TrackState]], None] | None = None,
                validate_box: Callable[[Frame, Box], None] | None = None) -> RunResult:
    """Track ``init_box`` through ``frames`` as target 1 (:func:`run_targets` with one target).

    ``validate_box(first_frame, box)`` may raise to reject the box once the
    frame size is known; the sinks and ``on_frame`` get ``{1: state}``.
    """
    validate = None if validate_box is None else (lambda frame, boxes: validate_box(frame, boxes[1]))
    return run_targets(MultiTargetTracker({1: tracker}), frames, {1: init_box}, sinks, max_frames=max_frames,
                       on_frame=on_frame, validate_boxes=validate)
