"""File sources: a video file or a folder of images, decoded one frame at a time.

Sources stream: they hold one decoded frame at a time, so memory stays flat
however long the video is.  They are the only place frames are read from disk.
A video's frames carry their presentation time (``Frame.timestamp``, seconds
from the start of its stream); a folder's frames carry none.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from ..errors import SourceError
from ..types import Frame

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

    A file after the first whose header cannot be read is left to decoding,
    which skips it (see :class:`ImageFolderSource`).

    Raises
    ------
    SourceError
        Naming the first file whose size differs from the first file's, or
        when the first file is not an image.
    """
    size = image_size(files[0])
    for file in files[1:]:
        try:
            other = image_size(file)
        except SourceError:
            continue
        if other != size:
            raise SourceError(f"image {file} is {other[0]}x{other[1]} but {files[0].name} is "
                              f"{size[0]}x{size[1]}: every frame of a folder must have one size")
    return size


#: Suffixes of JPEG files, which end with the end-of-image marker :data:`JPEG_END` when complete.
JPEG_SUFFIXES = {".jpg", ".jpeg"}
JPEG_END = b"\xff\xd9"


def is_truncated_jpeg(path: Path) -> bool:
    """True for a JPEG file whose last bytes hold no end-of-image marker (a copy or download cut short).

    libjpeg decodes such a file with its missing part grey; the marker may be
    followed by a few padding bytes, so the last 64 bytes are searched.
    """
    if path.suffix.lower() not in JPEG_SUFFIXES:
        return False
    try:
        with open(path, "rb") as file:
            file.seek(0, 2)
            file.seek(max(file.tell() - 64, 0))
            return JPEG_END not in file.read()
    except OSError:
        return True


class SkippedFrame:
    """A frame a source could not decode in the middle of a stream: ``index`` and why (``reason``)."""

    def __init__(self, index: int, reason: str) -> None:
        self.index = index
        self.reason = reason

    def __repr__(self) -> str:
        return f"SkippedFrame({self.index}, {self.reason!r})"


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

    A file in the middle that does not decode (corrupt, truncated, or of
    another size) is skipped: the source yields a frame with the previous
    image in its place, lists it in ``skipped`` (:class:`SkippedFrame`, its
    index in ``missing``) and calls ``on_skip`` with a message naming it, so
    a run predicts through it and keeps one box per frame.

    Parameters
    ----------
    folder
        Folder holding image files (png, jpg ...); other files are ignored.
    files
        Explicit file list (used by dataset loaders); overrides the listing.

    Raises
    ------
    SourceError
        If the folder does not exist, holds no images, its first image does
        not decode, or its images do not all have one size (the message
        names the first odd file).
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
        self.skipped: list[SkippedFrame] = []
        self.missing: set[int] = set()
        self.on_skip = None

    def __len__(self) -> int:
        return len(self.files)

    def _decode(self, file: Path) -> tuple[np.ndarray | None, str]:
        if is_truncated_jpeg(file):
            return None, f"image {file} is truncated"
        image = read_image(file)
        if image is None:
            return None, f"cannot decode image {file}"
        if image.shape[1::-1] != self.size:
            return None, (f"image {file} decodes as {image.shape[1]}x{image.shape[0]}, "
                          f"not {self.size[0]}x{self.size[1]}")
        return image, ""

    def __iter__(self) -> Iterator[Frame]:
        self.skipped, self.missing = [], set()
        previous = None
        for index, file in enumerate(self.files):
            image, reason = self._decode(file)
            if image is None:
                if previous is None:
                    self.decode_error = reason
                    raise SourceError(reason)
                self.skipped.append(SkippedFrame(index, reason))
                self.missing.add(index)
                if self.on_skip is not None:
                    self.on_skip(f"{reason}: frame {index} skipped")
                image = previous
            previous = image
            yield Frame(index, image)


class VideoSource:
    """Frames decoded from a video file by OpenCV (mp4, avi, webm ...).

    Where FFmpeg skips corrupt data in the middle and resynchronises, the
    frames' timestamps jump: the frames in between are yielded with the
    last decoded image in their place and listed in ``skipped`` and
    ``missing`` (as :class:`ImageFolderSource` does), ``on_skip`` is called
    once per gap, and the frames after it keep their true indices.  Each
    frame's ``timestamp`` is its presentation time in seconds (FFmpeg's pts
    from the stream's start, as OpenCV reports it).  A video
    that stops decoding before its announced frame count sets
    ``decode_error`` and ends.

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
        self._stamped = 1.0 <= fps <= 240.0   # timestamps can place frames only with a plausible rate
        self.fps = fps if self._stamped else 30.0
        self.decode_error: str | None = None
        self.skipped: list[SkippedFrame] = []
        self.missing: set[int] = set()
        self.on_skip = None

    def __len__(self) -> int:
        return self._count

    def _gap(self, start: int, stop: int) -> None:
        reason = "corrupt data in the video"
        self.skipped += [SkippedFrame(index, reason) for index in range(start, stop)]
        self.missing.update(range(start, stop))
        if self.on_skip is not None:
            frames = f"frame {start}" if stop - start == 1 else f"frames {start}-{stop - 1}"
            self.on_skip(f"{reason}: {frames} did not decode and are skipped")

    def __iter__(self) -> Iterator[Frame]:
        self.skipped, self.missing = [], set()
        capture = cv2.VideoCapture(str(self.path))
        try:
            index, first_ms, previous = 0, None, None
            while True:
                ok, image = capture.read()
                if not ok or image is None:
                    if self._count and index < self._count:
                        self.decode_error = f"decoding stopped at frame {index} of {self._count}"
                    return
                image = _as_bgr(image)
                milliseconds = capture.get(cv2.CAP_PROP_POS_MSEC)
                first_ms = milliseconds if first_ms is None else first_ms
                stamp = round((milliseconds - first_ms) * self.fps / 1000.0) if self._stamped else index
                if previous is not None and stamp > index:   # FFmpeg resynchronised after corrupt data
                    self._gap(index, stamp)
                    for missing in range(index, stamp):
                        yield Frame(missing, previous, timestamp=first_ms / 1000.0 + missing / self.fps)
                    index = stamp
                yield Frame(index, image, timestamp=milliseconds / 1000.0)
                previous = image
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
