"""Frame sources: a video file or a folder of images, decoded one frame at a time.

Sources stream: they hold one decoded frame at a time, so memory stays flat
however long the video is.  They are the only place frames are read from disk.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from .errors import SourceError
from .types import Frame

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"}


def _as_bgr(image: np.ndarray) -> np.ndarray:
    """Any decoded image -> ``(H, W, 3) uint8`` BGR."""
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


class ImageFolderSource:
    """Frames from the sorted image files of a folder.

    Parameters
    ----------
    folder
        Folder holding image files (png, jpg ...); other files are ignored.
    files
        Explicit file list (used by dataset loaders); overrides the listing.

    Raises
    ------
    SourceError
        If the folder does not exist or holds no images.
    """

    def __init__(self, folder: str | Path, files: list[Path] | None = None) -> None:
        self.path = Path(folder)
        if files is None:
            if not self.path.is_dir():
                raise SourceError(f"no such folder: {self.path}")
            files = sorted(p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise SourceError(f"folder holds no images: {self.path}")
        self.files = list(files)
        self.fps = 30.0
        self.decode_error: str | None = None

    def __len__(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[Frame]:
        for index, file in enumerate(self.files):
            image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
            if image is None:
                self.decode_error = f"cannot decode image {file}"
                if index == 0:
                    raise SourceError(self.decode_error)
                return
            if image.dtype != np.uint8:
                image = cv2.convertScaleAbs(image, alpha=255.0 / max(float(image.max()), 1.0))
            yield Frame(index, _as_bgr(image))


class VideoSource:
    """Frames decoded from a video file by OpenCV (mp4, avi, webm ...).

    Raises
    ------
    SourceError
        If the file is missing or OpenCV cannot decode its first frame.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"no such video file: {self.path}")
        capture = cv2.VideoCapture(str(self.path))
        ok = capture.isOpened()
        if ok:
            ok, _ = capture.read()
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if ok else 0
        fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0) if ok else 0.0
        capture.release()
        if not ok:
            raise SourceError(f"cannot decode video: {self.path}")
        self._count = max(count, 0)
        self.fps = fps if 1.0 <= fps <= 240.0 else 30.0
        self.decode_error: str | None = None

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[Frame]:
        capture = cv2.VideoCapture(str(self.path))
        try:
            index = 0
            while True:
                ok, image = capture.read()
                if not ok or image is None:
                    if self._count and index < self._count:
                        self.decode_error = f"decoding stopped at frame {index} of {self._count}"
                    return
                yield Frame(index, _as_bgr(image))
                index += 1
        finally:
            capture.release()


def open_source(path: str | Path) -> ImageFolderSource | VideoSource:
    """A source for ``path``: a folder of images or a video file."""
    path = Path(path)
    if path.is_dir():
        return ImageFolderSource(path)
    if not path.exists():
        raise SourceError(f"no such video file or folder: {path}")
    return VideoSource(path)
