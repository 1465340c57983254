"""vidtrack as a library: trackers in OpenCV's shape and a per-frame generator.

Two ways in, one loop underneath::

    t = vidtrack.create("mil")                  # like cv2.TrackerCSRT.create()
    t.init(frame, (x, y, w, h))                 # BGR uint8 image, 0-based box
    ok, (x, y, w, h) = t.update(next_frame)     # ok is False while the target is lost
    t.state.confidence, t.state.status          # the last TrackState

    for state in vidtrack.track("clip.mp4", (x, y, w, h), filter="mil"):
        print(state.index, state.box, state.confidence)

    for targets in vidtrack.track("clip.mp4", boxes=[box_a, box_b]):   # several targets: IDs 1, 2
        print({i: s.box for i, s in targets.items()})

A tracker's options are the fields of its frozen configuration
(``vidtrack filters NAME`` lists them): top-level fields as keywords
(``vidtrack.create("svk", seed=0, bins=8)``), any field by its dotted key in
``settings`` (``settings={"svr.C": 2.0}``), as the command line's
``--set KEY=VALUE`` does.

:func:`track_targets` is the loop; the command line (:func:`vidtrack.run.run_targets`,
which ``vidtrack eval`` also calls per job) and :func:`track` with ``boxes``
iterate it, and with one target it steps the tracker exactly as
:func:`track_frames` does, so a box from the library equals the box the CLI writes.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, TypeVar

import numpy as np

from .errors import UsageError
from .recipes import build_tracker, recipe_config, registry
from .targets import MultiTargetTracker
from .tracker import Tracker
from .types import Box, Frame, TrackState

__all__ = ["VidtrackTracker", "create", "filters", "track", "track_frames", "track_targets", "tracker_config",
           "as_box", "as_boxes", "as_image", "check_inside"]

_T = TypeVar("_T")


def as_box(box: Any) -> Box:
    """A :class:`~vidtrack.types.Box` from a Box, the text ``"x,y,w,h"`` or any 4-sequence (0-based pixels).

    Text is read by :meth:`Box.parse <vidtrack.types.Box.parse>`, the parser
    of the command line's ``--init-box`` and of the benchmark box files.

    Raises
    ------
    UsageError
        If ``box`` is not four finite numbers with a positive width and height.
    """
    if isinstance(box, Box):
        result = box
    elif isinstance(box, str):
        try:
            result = Box.parse(box)
        except ValueError:
            raise UsageError(f"box must be four numbers x,y,w,h, got {box!r}") from None
    else:
        try:
            values = np.asarray(box, dtype=float).ravel()
        except (TypeError, ValueError):
            raise UsageError(f"box must be four numbers x,y,w,h, got {box!r}") from None
        if values.size != 4:
            raise UsageError(f"box must be four numbers x,y,w,h, got {box!r}")
        result = Box.from_array(values)
    if not result.is_valid():
        raise UsageError(f"box must have finite coordinates and a positive width and height, got {result}")
    return result


def check_inside(box: Box, width: int, height: int, *, what: str = "box") -> None:
    """Reject an init ``box`` that does not lie mostly inside a ``width x height`` frame.

    The one in-frame check of the command line, the API and TraX
    (:meth:`Box.is_inside <vidtrack.types.Box.is_inside>`); ``what`` names
    the box in the message (``--init-box``).

    Raises
    ------
    UsageError
        ``<what> x,y,w,h lies outside the WxH frame``.
    """
    if not box.is_inside(width, height):
        raise UsageError(f"{what} {box} lies outside the {width}x{height} frame")


def as_boxes(boxes: Any) -> dict[int, Box]:
    """Target ID -> :class:`~vidtrack.types.Box` from a mapping ``{id: box}`` or a sequence of boxes (IDs 1, 2 ...).

    Each box is read by :func:`as_box`.

    Raises
    ------
    UsageError
        For no box at all, an ID that is not a positive int, or a malformed box.
    """
    if isinstance(boxes, Mapping):
        items = list(boxes.items())
    elif isinstance(boxes, (str, bytes, Box)) or not isinstance(boxes, Iterable):
        raise UsageError(f"boxes must be a list of boxes or a mapping ID -> box, got {type(boxes).__name__}")
    else:
        items = list(enumerate(boxes, start=1))
    if not items:
        raise UsageError("boxes must hold at least one box")
    result: dict[int, Box] = {}
    for key, box in items:
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or key < 1:
            raise UsageError(f"target IDs must be positive ints, got {key!r}")
        try:
            result[int(key)] = as_box(box)
        except UsageError as exc:
            raise UsageError(f"target {key}: {exc}") from None
    return dict(sorted(result.items()))


def as_image(image: Any) -> np.ndarray:
    """An ``(H, W, 3) uint8`` BGR array from a BGR, BGRA or grey ``uint8`` image of any size.

    Raises
    ------
    UsageError
        If ``image`` is not a 2-D or 3-D ``uint8`` array with 1, 3 or 4 channels.
    """
    if not isinstance(image, np.ndarray):
        raise UsageError(f"image must be a numpy array (H, W, 3) uint8 BGR, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise UsageError(f"image must be uint8 (as OpenCV decodes it), got {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 2:
        return np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4) or min(image.shape[:2]) < 1:
        raise UsageError(f"image must be (H, W, 3) BGR, (H, W, 4) BGRA or (H, W) grey, got shape {image.shape}")
    if image.shape[2] == 4:
        image = image[:, :, :3]
    return np.ascontiguousarray(image)


class VidtrackTracker:
    """A vidtrack tracker with OpenCV's tracker methods (``init``, ``update``).

    Build one with :func:`create`.  ``state`` is the last
    :class:`~vidtrack.types.TrackState` (box, confidence in [0, 1], status
    ``tracking``/``lost``, ``stages``), ``name`` the filter's name,
    ``seconds`` the time spent inside the tracker so far.

    Parameters
    ----------
    tracker
        A :class:`~vidtrack.tracker.Tracker`, as :func:`vidtrack.recipes.build_tracker` makes it.
    """

    def __init__(self, tracker: Tracker) -> None:
        self.tracker = tracker
        self.state: TrackState | None = None
        self.seconds = 0.0
        self.next_index_ = 0

    @property
    def name(self) -> str:
        """The registered tracker name (``mil``, ``kalman-cv`` ...)."""
        return self.tracker.name

    def init(self, image: np.ndarray, box: Any) -> None:
        """Start tracking ``box`` (``x, y, w, h``, 0-based pixels) in ``image`` (``(H, W, 3) uint8`` BGR).

        May be called again at any time to restart on a new box.

        Raises
        ------
        UsageError
            For a malformed image or box, or a box mostly outside the image.
        """
        image = as_image(image)
        box = as_box(box)
        check_inside(box, image.shape[1], image.shape[0])
        self.init_frame(Frame(0, image), box)

    def update(self, image: np.ndarray) -> tuple[bool, tuple[float, float, float, float]]:
        """Track one more frame: ``(ok, (x, y, w, h))``, ``ok`` False when the tracker reports the target lost.

        Raises
        ------
        UsageError
            For a malformed image, or when :meth:`init` was not called first.
        """
        if self.state is None:
            raise UsageError("call init(image, box) before update(image)")
        state = self.step_frame(Frame(self.next_index_, as_image(image)))
        return state.status != "lost", tuple(float(v) for v in state.box.as_array())

    def init_frame(self, frame: Frame, box: Box) -> TrackState:
        """:meth:`init` on a :class:`~vidtrack.types.Frame` (no checks); return the first state."""
        start = time.perf_counter()
        state = self.tracker.initialize(frame, box)
        self.seconds += time.perf_counter() - start
        return self._keep(frame, state)

    def step_frame(self, frame: Frame) -> TrackState:
        """:meth:`update` on a :class:`~vidtrack.types.Frame`; return its state."""
        start = time.perf_counter()
        state = self.tracker.step(frame)
        self.seconds += time.perf_counter() - start
        return self._keep(frame, state)

    def _keep(self, frame: Frame, state: TrackState) -> TrackState:
        self.state = state
        self.next_index_ = frame.index + 1
        return state

    def __repr__(self) -> str:
        return f"<vidtrack tracker {self.name!r}, state {self.state!r}>"


def _naming(name: str, make: Callable[[], _T]) -> _T:
    """``make()``, its UsageError about an option or a value of tracker ``name`` prefixed with the name."""
    try:
        return make()
    except UsageError as exc:
        if name not in registry() or str(exc).startswith(f"filter {name}"):
            raise
        raise UsageError(f"filter {name}: {exc}") from None


def tracker_config(name: str, settings: Mapping[str, Any] | None = None, **options: Any) -> Any:
    """The frozen configuration the tracker ``name`` is built from, with ``settings`` and ``options`` applied.

    ``settings`` maps dotted keys (``svr.C``) to values or strings (as the
    command line's ``--set`` gives them); ``options`` are top-level fields as
    keywords and are applied last.  None for a tracker without options.

    Raises
    ------
    UsageError
        For an unknown name (the message lists the valid ones), or an option
        the tracker does not take or a bad value (the message names the
        tracker and lists its options).
    """
    return _naming(name, lambda: recipe_config(name, {**(settings or {}), **options}))


def create(name: str, seed: int | None = 0, *, settings: Mapping[str, Any] | None = None,
           **options: Any) -> VidtrackTracker:
    """A tracker registered as ``name`` (see :func:`filters`), in OpenCV's shape.

    Parameters
    ----------
    name
        Tracker name, as ``vidtrack --filter`` takes it.
    seed
        Random seed (the CLI's ``--seed``; default 0).
    settings
        Options by dotted key (``{"svr.C": 2.0}``; strings are converted to
        the field's type), as the CLI's ``--config`` and ``--set`` give them.
    **options
        Top-level options as keywords (``model=``, ``detector=`` ...), applied
        after ``settings``.

    Raises
    ------
    UsageError
        For an unknown name, an option the tracker does not take or a bad
        value (the CLI's message).
    """
    return VidtrackTracker(_naming(name, lambda: build_tracker(name, seed=seed, settings=settings, **options)))


def filters() -> dict[str, str]:
    """Every registered filter name with its one-line description, sorted by name."""
    recipes = registry()
    return {name: recipes[name].description for name in sorted(recipes)}


def as_frames(source: Any) -> Iterable[Frame]:
    """Frames from a video path, a frame folder, or an iterable of images or :class:`~vidtrack.types.Frame`.

    A string may also name a live input as on the command line
    (:func:`vidtrack.sources.open_input`): a camera index (``"0"``), a stream
    URL (``"rtsp://..."``, ``"http://..."``) or ``"-"`` for stdin, read live
    (the newest frame; frames the tracker cannot keep up with are dropped).

    Raises
    ------
    SourceError
        For a path that does not exist or cannot be decoded.
    UsageError
        For a source that is neither a path nor iterable.
    """
    if isinstance(source, str):
        from .sources import open_input

        return open_input(source)
    if isinstance(source, Path):
        from .sources import open_source

        return open_source(source)
    if isinstance(source, np.ndarray) and source.ndim < 4:
        raise UsageError("source must be a video path, a frame folder or an iterable of images, got one image")
    try:
        iterator = iter(source)
    except TypeError:
        raise UsageError(f"source must be a video path, a frame folder or an iterable of images, "
                         f"got {type(source).__name__}") from None
    return (item if isinstance(item, Frame) else Frame(index, as_image(item))
            for index, item in enumerate(iterator))


def track_frames(tracker: VidtrackTracker, frames: Iterable[Frame], box: Box, *, max_frames: int | None = None,
                 validate_box: Callable[[Frame, Box], None] | None = None) -> Iterator[tuple[Frame, TrackState]]:
    """The tracking loop: ``(frame, state)`` for every frame, the first initialising on ``box``.

    ``validate_box(first_frame, box)`` may raise to reject the box once the
    frame size is known; at most ``max_frames`` frames are tracked.  The time
    spent tracking accumulates in ``tracker.seconds``.
    """
    for count, frame in enumerate(frames):
        if max_frames is not None and count >= max_frames:
            return
        if count == 0:
            if validate_box is not None:
                validate_box(frame, box)
            state = tracker.init_frame(frame, box)
        else:
            state = tracker.step_frame(frame)
        yield frame, state


def track_targets(multi: MultiTargetTracker, frames: Iterable[Frame], boxes: Mapping[int, Box], *,
                  max_frames: int | None = None,
                  validate_boxes: Callable[[Frame, Mapping[int, Box]], None] | None = None
                  ) -> Iterator[tuple[Frame, dict[int, TrackState]]]:
    """The tracking loop of several targets: ``(frame, {id: state})`` for every frame, the first initialising.

    ``validate_boxes(first_frame, boxes)`` may raise to reject the boxes once
    the frame size is known; at most ``max_frames`` frames are tracked.  A
    frame whose index is in ``frames.missing`` (a source's frames that did not
    decode) is only predicted (:meth:`MultiTargetTracker.predict_only`).  The
    time spent tracking accumulates in ``multi.seconds``.
    """
    for count, frame in enumerate(frames):
        if max_frames is not None and count >= max_frames:
            return
        if count == 0:
            if validate_boxes is not None:
                validate_boxes(frame, boxes)
            states = multi.initialize(frame, boxes)
        elif frame.index in getattr(frames, "missing", ()):
            states = multi.predict_only(frame)
        else:
            states = multi.step(frame)
        yield frame, states


def track(source: Any, box: Any = None, filter: str = "mil", *, boxes: Any = None, seed: int | None = 0,
          max_frames: int | None = None, settings: Mapping[str, Any] | None = None,
          **options: Any) -> Iterator[TrackState] | Iterator[dict[int, TrackState]]:
    """Track ``box`` (or every box of ``boxes``) through ``source``, yielding each frame's state(s).

    Parameters
    ----------
    source
        A video file, a folder of frame images, a camera index or stream URL
        as a string (read live, see :func:`as_frames`), or any iterable of
        BGR ``uint8`` images (or :class:`~vidtrack.types.Frame`).
    box
        ``x, y, w, h`` of the object in the first frame, 0-based pixels: one
        :class:`~vidtrack.types.TrackState` is yielded per frame.
    filter
        Tracker name (see :func:`filters`); default ``mil``.
    boxes
        Instead of ``box``, several targets: a list of boxes (target IDs 1, 2
        ...) or a mapping ID -> box.  Each target gets its own tracker (all
        with ``seed``); per frame a dict ID -> TrackState (IDs ascending) is
        yielded (:class:`~vidtrack.targets.MultiTargetTracker`: the trackers
        share each frame, run side by side and know about each other).
    seed, settings, **options
        As for :func:`create`.
    max_frames
        Stop after this many frames.

    Raises
    ------
    UsageError, SourceError
        For a bad name, option, box or source (raised before the first frame is tracked).
    """
    if (box is None) == (boxes is None):
        raise UsageError("give either box (one target) or boxes (several targets)")
    if boxes is not None:
        targets = as_boxes(boxes)
        multi = MultiTargetTracker({i: create(filter, seed=seed, settings=settings, **options).tracker
                                    for i in targets})
        frames = as_frames(source)

        def check_all(frame: Frame, boxes: Mapping[int, Box]) -> None:
            for i, b in boxes.items():
                check_inside(b, frame.width, frame.height, what=f"target {i}'s box")

        def generate() -> Iterator[dict[int, TrackState]]:
            try:
                for _, states in track_targets(multi, frames, targets, max_frames=max_frames,
                                               validate_boxes=check_all):
                    yield states
            finally:
                multi.close()
                _close_source(frames)

        return generate()
    tracker = create(filter, seed=seed, settings=settings, **options)
    box = as_box(box)
    frames = as_frames(source)

    def check(frame: Frame, box: Box) -> None:
        check_inside(box, frame.width, frame.height)

    def generate_one() -> Iterator[TrackState]:
        try:
            for _, state in track_frames(tracker, frames, box, max_frames=max_frames, validate_box=check):
                yield state
        finally:
            _close_source(frames)

    return generate_one()


def _close_source(frames: Any) -> None:
    """Stop a live source's reader (a camera or stream stays open otherwise); files need nothing."""
    close = getattr(frames, "close", None)
    if callable(close):
        close()
