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


#: FFmpeg demuxers and decoders that read text files as "video" (a README, a ground-truth file).
TEXT_FORMATS = {"tty", "bin", "xbin", "adf", "idf"}
TEXT_CODECS = {"ansi", "bintext", "xbin", "idf"}

#: EXIF orientations that swap width and height (rotations by 90 or 270 degrees).
_SWAPPING_ORIENTATIONS = {5, 6, 7, 8}
_EXIF_FORMATS = {"JPEG", "MPO", "TIFF", "WEBP"}


def _as_bgr(image: np.ndarray) -> np.ndarray:
    """Any decoded image -> ``(H, W, 3) uint8`` BGR (16-bit: the high byte; grey and BGRA converted)."""
    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)  # 16-bit -> 8-bit by the high byte, the same for every frame
    elif image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(float(np.nanmax(image)), 1e-12))
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


def read_image(path: str | Path) -> np.ndarray | None:
    """Decode one image file as ``(H, W, 3) uint8`` BGR, EXIF orientation applied; None if undecodable.

    Grey, BGRA and 16-bit files are converted (16-bit by the high byte).
    """
    image = cv2.imread(str(path), cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)
    return None if image is None else _as_bgr(image)


def image_size(path: str | Path) -> tuple[int, int]:
    """``(width, height)`` of an image file as :func:`read_image` returns it, from its header only.

    Raises
    ------
    SourceError
        When the file is not an image Pillow can open.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            width, height = image.size
            # EXIF orientation: JPEG/TIFF/WebP only (finding a PNG's eXIf chunk reads the whole file)
            orientation = image.getexif().get(0x0112) if image.format in _EXIF_FORMATS else None
    except (OSError, UnidentifiedImageError, ValueError):
        raise SourceError(f"cannot decode image {path}") from None
    if orientation in _SWAPPING_ORIENTATIONS:
        width, height = height, width
    return int(width), int(height)


def check_same_size(files: list[Path]) -> tuple[int, int]:
    """The common ``(width, height)`` of ``files``, read from their headers.

    Raises
    ------
    SourceError
        Naming the first file whose size differs from the first file's, or
        the first file that is not an image.
    """
    size = image_size(files[0])
    for file in files[1:]:
        other = image_size(file)
        if other != size:
            raise SourceError(f"image {file} is {other[0]}x{other[1]} but {files[0].name} is "
                              f"{size[0]}x{size[1]}: every frame of a folder must have one size")
    return size


def probe_container(path: Path) -> None:
    """Reject a file that FFmpeg does not read as a video container (by content, not by name).

    Raises
    ------
    SourceError
        When FFmpeg cannot open it, finds no video stream in it, or reads it
        as text (its ``tty`` demuxer renders any text file as frames).
    """
    import av

    try:
        with av.open(str(path), metadata_errors="ignore") as container:
            format_names = set(container.format.name.split(","))
            streams = list(container.streams.video)
            codecs = {stream.codec_context.name for stream in streams}
    except (av.FFmpegError, OSError, ValueError):
        raise SourceError(f"cannot decode video {path}: FFmpeg finds no video container in it") from None
    if format_names & TEXT_FORMATS or codecs & TEXT_CODECS:
        raise SourceError(f"not a video file: {path} (it is text)")
    if not streams:
        raise SourceError(f"not a video file: {path} (no video stream in its "
                          f"{container.format.name} container)")


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
        If the folder does not exist, holds no images, or its images do not
        all have one size (the message names the first odd file).
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
        self.size = check_same_size(self.files)  # one clear line now, not a confused tracker later
        self.fps = 30.0
        self.decode_error: str | None = None

    def __len__(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[Frame]:
        for index, file in enumerate(self.files):
            image = read_image(file)
            if image is None:
                self.decode_error = f"cannot decode image {file}"
                if index == 0:
                    raise SourceError(self.decode_error)
                return
            if image.shape[1::-1] != self.size:
                raise SourceError(f"image {file} decodes as {image.shape[1]}x{image.shape[0]}, "
                                  f"not {self.size[0]}x{self.size[1]}")
            yield Frame(index, image)


class VideoSource:
    """Frames decoded from a video file by OpenCV (mp4, avi, webm ...).

    Raises
    ------
    SourceError
        If the file is missing, is not a video container (see
        :func:`probe_container`), or has no decodable frame.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"no such video file: {self.path}")
        probe_container(self.path)
        capture = cv2.VideoCapture(str(self.path))
        ok = capture.isOpened()
        if ok:
            ok, _ = capture.read()
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if ok else 0
        fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0) if ok else 0.0
        capture.release()
        if not ok:
            raise SourceError(f"video holds no decodable frame: {self.path}")
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
