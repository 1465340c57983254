"""Loopback servers for the live tests: an MPEG-TS stream over TCP and an MJPEG stream over HTTP, on 127.0.0.1 only.

Each server listens on a free port the OS picks, serves one client from a
thread at a given frame rate, and is stopped by the test (``with`` block).
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np

HOST = "127.0.0.1"


def write_ts_clip(path: Path, images: list[np.ndarray], fps: int = 25) -> Path:
    """Encode ``images`` (BGR) as MPEG-4 Part 2 in MPEG-TS, without B-frames (each frame decodes on arrival)."""
    import av

    height, width = images[0].shape[:2]
    with av.open(str(path), "w", format="mpegts") as container:
        stream = container.add_stream("mpeg4", rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.codec_context.max_b_frames = 0
        stream.bit_rate = 2_000_000
        for image in images:
            for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return path


def ts_frame_chunks(path: Path) -> list[bytes]:
    """The bytes of an MPEG-TS file cut at each video packet's start: chunk k carries frame k."""
    import av

    data = path.read_bytes()
    with av.open(str(path)) as container:
        starts = sorted(p.pos for p in container.demux(video=0) if p.size and p.pos is not None and p.pos >= 0)
    cuts = [0, *starts[1:], len(data)]
    return [data[a:b] for a, b in zip(cuts, cuts[1:])]


class TsServer:
    """One MPEG-TS client over TCP: one frame's bytes every ``1 / fps`` seconds.

    Parameters
    ----------
    chunks
        :func:`ts_frame_chunks` of a clip.
    fps
        Frames per second sent.
    cut_at
        Frame at which the stream is cut (None: sent whole, then the
        connection is closed).  ``cut="stall"``: nothing more is sent, the
        connection is held open and new connections are refused;
        ``cut="reset"``: the connection is reset (TCP RST).
    """

    def __init__(self, chunks: list[bytes], fps: float, *, cut_at: int | None = None, cut: str = "stall") -> None:
        self.chunks, self.fps, self.cut_at, self.cut = chunks, fps, cut_at, cut
        self.listener = socket.create_server((HOST, 0))
        self.listener.settimeout(30)
        self.port = self.listener.getsockname()[1]
        self.url = f"tcp://{HOST}:{self.port}"
        self.sent = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def _serve(self) -> None:
        try:
            connection, _ = self.listener.accept()
        except OSError:
            return
        with connection:
            start = time.monotonic()
            for index, chunk in enumerate(self.chunks):
                if index == self.cut_at:
                    self.listener.close()   # a reconnect is refused
                    if self.cut == "reset":
                        connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                        return
                    self._stop.wait(60)    # stalled: connected, silent
                    return
                try:
                    connection.sendall(chunk)
                except OSError:
                    return
                self.sent += 1
                if self._stop.wait(max(start + (index + 1) / self.fps - time.monotonic(), 0)):
                    return

    def __enter__(self) -> "TsServer":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self.listener.close()
        self._thread.join(5)


class MjpegServer:
    """An HTTP MJPEG stream (``multipart/x-mixed-replace``) of ``images`` at ``fps``, then the response ends."""

    def __init__(self, images: list[np.ndarray], fps: float) -> None:
        jpegs = [cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes() for image in images]
        stop = self._stop = threading.Event()

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                start = time.monotonic()
                for index, jpeg in enumerate(jpegs):
                    self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n"
                                     + f"Content-Length: {len(jpeg)}\r\n\r\n".encode() + jpeg + b"\r\n")
                    self.wfile.flush()
                    if stop.wait(max(start + (index + 1) / fps - time.monotonic(), 0)):
                        return
                self.close_connection = True

            def log_message(self, *args) -> None:   # no request lines on stderr
                pass

        self.server = ThreadingHTTPServer((HOST, 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://{HOST}:{self.server.server_address[1]}/video.mjpg"
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> "MjpegServer":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(5)


class FileServer:
    """Plain HTTP serving the files of ``folder`` (for inputs that are not video)."""

    def __init__(self, folder: Path) -> None:
        from functools import partial
        from http.server import SimpleHTTPRequestHandler

        class Quiet(SimpleHTTPRequestHandler):
            def log_message(self, *args) -> None:
                pass

        self.server = ThreadingHTTPServer((HOST, 0), partial(Quiet, directory=str(folder)))
        self.server.daemon_threads = True
        self.url = f"http://{HOST}:{self.server.server_address[1]}"
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> "FileServer":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(5)


def closed_port() -> int:
    """A port on 127.0.0.1 that nothing listens on (bound, then released)."""
    with socket.create_server((HOST, 0)) as probe:
        return probe.getsockname()[1]


class SlowMeasurer:
    """Any measurer, ``seconds`` of wall clock slower per measured frame (a busy loop holding the GIL, as a
    heavy Python tracker would)."""

    def __init__(self, inner, seconds: float) -> None:
        self.inner = inner
        self.seconds = seconds

    def initialize(self, frame, box) -> None:
        self.inner.initialize(frame, box)

    def measure(self, frame, prior):
        end = time.perf_counter() + self.seconds
        while time.perf_counter() < end:
            pass
        return self.inner.measure(frame, prior)

    def learn(self, frame, posterior) -> None:
        self.inner.learn(frame, posterior)


def slow_recipe(seconds: float):
    """A recipe: ``kalman-cv`` made ``seconds`` slower per frame (:class:`SlowMeasurer`); register it in a test."""
    from vidtrack.recipes import Recipe, registry

    base = registry()["kalman-cv"]

    def build(config, seed=None):
        tracker = base.build(config, seed=seed)
        tracker.measurer = SlowMeasurer(tracker.measurer, seconds)
        return tracker

    return Recipe(f"kalman-cv taking {seconds:g} s more per frame (tests only)", build, base.config)
