"""Annotated video sink: every frame with each target's boxes and label (drawn by :mod:`.overlay`).

The only module besides the sources that calls OpenCV's video I/O.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import cv2

from ..errors import OutputError
from ..types import Frame, TrackState
from .overlay import draw_overlay


def as_targets(targets: Mapping[int, TrackState] | TrackState) -> Mapping[int, TrackState]:
    """``targets`` as a mapping target ID -> state: a single :class:`TrackState` is target 1."""
    return {1: targets} if isinstance(targets, TrackState) else targets


class AnnotatedVideoSink:
    """Writes the annotated frames to a video: MJPG for ``.avi`` (OpenCV), else H.264 (PyAV).

    ``.mp4``/``.mov``/``.m4v`` are fragmented MP4 (:mod:`vidtrack.sinks.h264`):
    after a hard stop (``kill -9``, power cut) the file plays up to its last
    complete fragment, so at most ``batch`` of the last frames are missing.
    """

    def __init__(self, path: str | Path, *, filter_name: str, fps: float = 30.0, batch: int = 30) -> None:
        self.path = Path(path)
        self.filter_name = filter_name
        self.fps = fps
        self.batch = batch
        self._writer = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with open(self.path, "wb"):
                pass  # fail now, with a clear message, if the path is not writable
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from None

    def _open(self, width: int, height: int) -> None:
        if self.path.suffix.lower() != ".avi":
            from .h264 import H264Writer

            self._writer = H264Writer(self.path, fps=self.fps, batch=self.batch)
            return
        fourcc = cv2.VideoWriter_fourcc(*"MJPG")
        self._writer = cv2.VideoWriter(str(self.path), fourcc, self.fps, (width, height))
        if not self._writer.isOpened():
            raise OutputError(f"cannot write video {self.path}: no encoder for {self.path.suffix or 'this name'}")

    def write(self, frame: Frame, targets: Mapping[int, TrackState] | TrackState) -> None:
        """Append ``frame`` with every target drawn (target ID -> state; a single state is target 1)."""
        if self._writer is None:
            self._open(frame.width, frame.height)
        self._writer.write(draw_overlay(frame.image, as_targets(targets), frame_index=frame.index,
                                        filter_name=self.filter_name))

    def close(self) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.release() if isinstance(writer, cv2.VideoWriter) else writer.close()
