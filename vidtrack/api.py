"""vidtrack as a library: trackers in OpenCV's shape and a per-frame generator.

Two ways in, one loop underneath::

    t = vidtrack.create("mil")                  # like cv2.TrackerCSRT.create()
    t.init(frame, (x, y, w, h))                 # BGR uint8 image, 0-based box
    ok, (x, y, w, h) = t.update(next_frame)     # ok is False while the target is lost
    t.state.confidence, t.state.status          # the last TrackState

    for state in vidtrack.track("clip.mp4", (x, y, w, h), filter="mil"):
        print(state.index, state.box, state.confidence)

:func:`track_frames` is the loop; the command line (:func:`vidtrack.run.run_tracker`,
which ``vidtrack eval`` also calls per job) and :func:`track` both iterate it,
so a box from the library equals the box the CLI writes.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from .errors import UsageError
from .recipes import build_tracker, registry
from .tracker import Tracker
from .types import Box, Frame, TrackState

__all__ = ["VidtrackTracker", "create", "filters", "track", "track_frames", "as_box", "as_image"]


def as_box(box: Any) -> Box:
    """A :class:`~vidtrack.types.Box` from a Box or any 4-sequence ``x, y, w, h`` (0-based pixels).

    Raises
    ------
    UsageError
        If ``box`` is not four finite numbers with a positive width and height.
    """
    if isinstance(box, Box):
        result = box
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
        A :class:`~vidtrack.tracker.Tracker`, as :func:`~vidtrack.tracker.build_tracker` makes it.
    """

    def __init__(self, tracker: Tracker) -> None:
        self.tracker = tracker
        self.state: TrackState | None = None
        self.seconds = 0.0
        self.next_index_ = 0

    @property
    def name(self) -> str:
        """The registered filter name (``mil``, ``kalman-cv`` ...)."""
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
        if box.clipped(image.shape[1], image.shape[0]).area < 0.5 * box.area:
            raise UsageError(f"box {box} lies outside the {image.shape[1]}x{image.shape[0]} image")
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


def create(name: str, seed: int | None = 0, **options: Any) -> VidtrackTracker:
    """A tracker registered as ``name`` (see :func:`filters`), in OpenCV's shape.

    Parameters
    ----------
    name
        Filter name, as ``vidtrack --filter`` takes it.
    seed
        Random seed (the CLI's ``--seed``; default 0).
    **options
        Recipe options, as the CLI passes them (``model=``, ``detector=`` ...).

    Raises
    ------
    UsageError
        For an unknown name or an option the filter does not take (the CLI's message).
    """
    return VidtrackTracker(build_tracker(name, seed=seed, **options))


def filters() -> dict[str, str]:
    """Every registered filter name with its one-line description, sorted by name."""
    recipes = registry()
    return {name: recipes[name].description for name in sorted(recipes)}


def as_frames(source: Any) -> Iterable[Frame]:
    """Frames from a video path, a frame folder, or an iterable of images or :class:`~vidtrack.types.Frame`.

    Raises
    ------
    SourceError
        For a path that does not exist or cannot be decoded.
    UsageError
        For a source that is neither a path nor iterable.
    """
    if isinstance(source, (str, Path)):
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


def track(source: Any, box: Any, filter: str = "mil", *, seed: int | None = 0, max_frames: int | None = None,
          **options: Any) -> Iterator[TrackState]:
    """Track ``box`` through ``source``, yielding one :class:`~vidtrack.types.TrackState` per frame.

    Parameters
    ----------
    source
        A video file, a folder of frame images, or any iterable of BGR
        ``uint8`` images (or :class:`~vidtrack.types.Frame`).
    box
        ``x, y, w, h`` of the object in the first frame, 0-based pixels.
    filter
        Filter name (see :func:`filters`); default ``mil``.
    seed, max_frames, **options
        As for :func:`create`; stop after ``max_frames`` frames.

    Raises
    ------
    UsageError, SourceError
        For a bad name, option, box or source (raised before the first frame is tracked).
    """
    tracker = create(filter, seed=seed, **options)
    box = as_box(box)
    frames = as_frames(source)

    def check(frame: Frame, box: Box) -> None:
        if box.clipped(frame.width, frame.height).area < 0.5 * box.area:
            raise UsageError(f"box {box} lies outside the {frame.width}x{frame.height} frame")

    return (state for _, state in track_frames(tracker, frames, box, max_frames=max_frames, validate_box=check))
