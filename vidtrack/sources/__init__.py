"""Frame sources: video files and frame folders (:mod:`.files`), streams, stdin and cameras (:mod:`.streams`),
and live mode (:mod:`.live`).

:func:`open_input` turns what a user types into a source: ``-`` is a video
piped on stdin, a number a camera index, ``scheme://...`` a stream FFmpeg
reads (rtsp, rtmp, http(s) including MJPEG, tcp, udp, srt ...), anything else
a video file or a folder of images (:func:`open_source`).  Cameras and
streams are read live (:class:`~vidtrack.sources.live.LiveSource`: the
tracker takes the newest frame, older ones are dropped); a file is read live,
at its own frame rate, with ``realtime=True``.
"""

from __future__ import annotations

import re

from .files import (IMAGE_SUFFIXES, JPEG_END, JPEG_SUFFIXES, TEXT_CODECS, TEXT_FORMATS, ImageFolderSource,
                    SkippedFrame, VideoSource, check_same_size, image_size, is_truncated_jpeg, open_source,
                    probe_container, read_image)
from .live import FileClock, LiveSource
from .streams import DEFAULT_STREAM_TIMEOUT, RECONNECT_DELAYS, CameraStream, PyAVStream, StreamLost

__all__ = [
    "IMAGE_SUFFIXES", "JPEG_END", "JPEG_SUFFIXES", "TEXT_CODECS", "TEXT_FORMATS", "ImageFolderSource",
    "SkippedFrame", "VideoSource", "check_same_size", "image_size", "is_truncated_jpeg", "open_source",
    "probe_container", "read_image", "FileClock", "LiveSource", "DEFAULT_STREAM_TIMEOUT", "RECONNECT_DELAYS",
    "CameraStream", "PyAVStream", "StreamLost", "input_kind", "open_input",
]

_URL = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*://")
_CAMERA = re.compile(r"\d+")
STDIN = "-"


def input_kind(text: str) -> str:
    """``"stdin"`` for ``-``, ``"camera"`` for a number, ``"stream"`` for ``scheme://...``, else ``"file"``.

    A file whose name is a number is written ``./0``.
    """
    if text == STDIN:
        return "stdin"
    if _CAMERA.fullmatch(text):
        return "camera"
    if _URL.match(text):
        return "stream"
    return "file"


def open_input(text: str, *, realtime: bool = False,
               stream_timeout: float = DEFAULT_STREAM_TIMEOUT) -> ImageFolderSource | VideoSource | LiveSource:
    """The source ``text`` names (see :func:`input_kind`).

    Parameters
    ----------
    text
        ``-``, a camera index, a stream URL, a video file or a frame folder.
    realtime
        Read a file live, at its own frame rate, dropping the frames the
        tracker cannot keep up with; read stdin live (newest frame, no
        back-pressure on the writer).  Cameras and streams are always live.
    stream_timeout
        Seconds a stream or camera may send nothing before it counts as
        stalled (then it is reopened, see
        :data:`~vidtrack.sources.streams.RECONNECT_DELAYS`).

    Raises
    ------
    SourceError
        When the input cannot be opened, is not video or has no frame.
    """
    kind = input_kind(text)
    if kind == "stdin":
        import os
        import sys

        if sys.stdin is None or os.isatty(0):
            from ..errors import SourceError

            raise SourceError("stdin is a terminal: pipe a video into 'vidtrack -'")
        return LiveSource(PyAVStream("pipe:0", label="the video on stdin", timeout=None, reconnect_delays=()), drop=realtime)
    if kind == "camera":
        return LiveSource(CameraStream(int(text), timeout=stream_timeout))
    if kind == "stream":
        return LiveSource(PyAVStream(text, timeout=stream_timeout))
    source = open_source(text)
    return LiveSource(FileClock(source)) if realtime else source
