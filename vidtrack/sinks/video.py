"""Annotated video sink: the frame with predicted, measured and estimated boxes.

The only module besides the sources that calls OpenCV's video I/O.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import OutputError
from ..types import Box, Frame, TrackState

ESTIMATE_COLOUR = (0, 220, 0)       # green: the estimate while tracking
LOST_COLOUR = (0, 0, 230)           # red: the estimate (prediction) while lost
MEASURED_COLOUR = (0, 200, 255)     # amber: the raw measurement
PREDICTED_COLOUR = (255, 160, 0)    # blue: the prior
REGION_COLOUR = (160, 160, 160)     # grey: the search region


def _rect(image: np.ndarray, box: Box | None, colour, thickness: int = 1) -> None:
    if box is None or not box.is_valid():
        return
    x, y, w, h = box.as_array()
    cv2.rectangle(image, (int(round(x)), int(round(y))), (int(round(x + w)), int(round(y + h))),
                  colour, thickness, cv2.LINE_AA)


def annotate(image: np.ndarray, state: TrackState, filter_name: str) -> np.ndarray:
    """A copy of ``image`` ``(H, W, 3) uint8`` BGR with the state drawn on it."""
    out = image.copy()
    _rect(out, state.search_region, REGION_COLOUR)
    _rect(out, state.predicted, PREDICTED_COLOUR)
    _rect(out, state.measured, MEASURED_COLOUR)
    lost = state.status == "lost"
    _rect(out, state.box, LOST_COLOUR if lost else ESTIMATE_COLOUR, 2)
    scale = max(0.35, min(out.shape[1], out.shape[0]) / 600.0)
    text = f"#{state.index} {filter_name} conf {state.confidence:.2f} {state.status}"
    org = (4, int(14 * scale / 0.35 * 0.9) + 2)
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale,
                LOST_COLOUR if lost else (255, 255, 255), 1, cv2.LINE_AA)
    return out


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

    def write(self, frame: Frame, targets) -> None:
        if self._writer is None:
            self._open(frame.width, frame.height)
        self._writer.write(annotate(frame.image, targets[min(targets)], self.filter_name))

    def close(self) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.release() if isinstance(writer, cv2.VideoWriter) else writer.close()
