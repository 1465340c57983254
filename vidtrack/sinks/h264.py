"""H.264 in fragmented MP4 through PyAV: a video that survives ``kill -9`` and plays in a browser.

A plain MP4 keeps its index (the ``moov`` atom) at the end, written on close:
a process killed before that leaves a file no player opens.  A fragmented
MP4 writes an empty ``moov`` first and then one self-contained fragment
(``moof`` + ``mdat``) per keyframe interval, so after a hard stop every
fragment already written plays; only the frames since the last keyframe
(at most ``batch`` of them) are lost.  ``tune=zerolatency`` makes libx264
emit each frame's packet at once (no B-frames, no look-ahead), and the
muxer's ``flush_packets`` hands each fragment to the operating system as
soon as it is complete.  H.264 yuv420p in MP4 is what web browsers play.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import OutputError

#: ``movflags`` of a fragmented MP4 that needs no rewrite on close (see the module docstring).
FRAGMENTED_MOVFLAGS = "frag_keyframe+empty_moov+default_base_moof"
#: Containers written fragmented; others (``.mkv``) get H.264 in their own container.
FRAGMENTED_SUFFIXES = {".mp4", ".m4v", ".mov"}


def even_frame(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` -> ``(H + H % 2, W + W % 2, 3)``: yuv420p needs even sides (last row/column repeated)."""
    pad_h, pad_w = image.shape[0] % 2, image.shape[1] % 2
    if not (pad_h or pad_w):
        return image
    return np.pad(image, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")


class H264Writer:
    """Writes ``(H, W, 3) uint8`` BGR frames as H.264 (libx264), fragmented for ``.mp4``/``.mov``.

    Parameters
    ----------
    path
        Output file; the suffix picks the container (``.mp4``, ``.mov``, ``.m4v``: fragmented MP4).
    fps
        Frame rate written in the file.
    batch
        Keyframe interval = fragment length in frames: after a hard stop at
        most this many of the last frames are missing from the file.
    crf
        libx264 constant rate factor (lower is better quality, larger files).
    """

    def __init__(self, path: str | Path, *, fps: float = 30.0, batch: int = 30, crf: int = 23) -> None:
        self.path = Path(path)
        self.fps = fps
        self.batch = int(batch)
        self.crf = int(crf)
        self.frames_ = 0
        self._container = None
        self._stream = None

    def _open(self, width: int, height: int) -> None:
        import av

        fragmented = self.path.suffix.lower() in FRAGMENTED_SUFFIXES
        options = {"movflags": FRAGMENTED_MOVFLAGS, "flush_packets": "1"} if fragmented else {}
        try:
            container = av.open(str(self.path), mode="w", format="mp4" if fragmented else None, options=options)
        except (av.FFmpegError, OSError, ValueError) as exc:
            raise OutputError(f"cannot write video {self.path}: {exc}") from None
        self._rate = Fraction(self.fps).limit_denominator(1001)
        try:
            stream = container.add_stream("libx264", rate=self._rate)
        except (av.FFmpegError, ValueError) as exc:
            container.close()
            raise OutputError(f"cannot write video {self.path}: no H.264 encoder ({exc})") from None
        stream.width, stream.height = width, height
        stream.pix_fmt = "yuv420p"
        stream.codec_context.gop_size = self.batch
        stream.options = {"preset": "veryfast", "tune": "zerolatency", "crf": str(self.crf),
                          "keyint": str(self.batch), "min-keyint": str(self.batch), "scenecut": "0"}
        self._container, self._stream = container, stream

    def write(self, image: np.ndarray) -> None:
        """Encode one ``(H, W, 3) uint8`` BGR frame (odd sides padded by one row/column).

        Raises
        ------
        OutputError
            :class:`~vidtrack.sinks.base.WriteFailed` for a full disk (the
            file is then closed, keeping every fragment written before).
        """
        import av

        image = even_frame(np.ascontiguousarray(image))
        if self._container is None:
            self._open(image.shape[1], image.shape[0])
        frame = av.VideoFrame.from_ndarray(image, format="bgr24")
        frame.pts = self.frames_
        frame.time_base = 1 / self._rate
        try:
            for packet in self._stream.encode(frame):
                self._container.mux(packet)
        except (av.FFmpegError, OSError) as exc:   # a full disk: the fragments written so far stay playable
            self._abandon()
            raise self._error(exc) from None
        self.frames_ += 1

    def _error(self, exc: BaseException) -> OutputError:
        from .base import failed_write

        if isinstance(exc, OSError):
            return failed_write(self.path, exc)
        return OutputError(f"cannot write video {self.path}: {exc}")

    def _abandon(self) -> None:
        """Close the file after a failed write, without flushing the encoder (nothing more can be written)."""
        container, self._container = self._container, None
        if container is not None:
            try:
                container.close()
            except Exception:   # the file keeps the fragments written before the failure
                pass

    def close(self) -> None:
        """Flush the encoder and finish the file (safe to call twice).

        Raises
        ------
        OutputError
            :class:`~vidtrack.sinks.base.WriteFailed` for a full disk; the
            file keeps every fragment written before.
        """
        import av

        container = self._container
        if container is None:
            return
        try:
            for packet in self._stream.encode(None):
                container.mux(packet)
        except (av.FFmpegError, OSError) as exc:
            self._abandon()
            raise self._error(exc) from None
        self._container = None
        try:
            container.close()
        except (av.FFmpegError, OSError) as exc:
            raise self._error(exc) from None


def count_frames(path: str | Path) -> int:
    """Frames PyAV decodes from ``path`` (for tests and checks of a killed run's video); 0 if unreadable."""
    import av

    count = 0
    try:
        with av.open(str(path)) as container:
            for _ in container.decode(video=0):
                count += 1
    except (av.FFmpegError, OSError, ValueError):
        pass
    return count
