"""`vidtrack trax` driven by the TraX reference client (vot-trax): the boxes of `vidtrack eval`, re-initialisation;
and by a raw pipe client: malformed messages, a client that disconnects mid-message or stops reading, an image
that vanishes mid-session (one line on stderr, exit 2 or 1, never a traceback or a hang)."""

import subprocess
import sys
import time

import numpy as np
import pytest
from trax import TraxException
from trax.client import Client
from trax.image import FileImage
from trax.region import Rectangle

from vidtrack.cli import main
from vidtrack.eval.datasets import load_sequence, read_boxes
from vidtrack.types import Box

from conftest import SEQUENCES, needs_sequences

SEQUENCE = "Football1"   # 74 frames, every one annotated, the box stays inside the frame


class TraxTracker:
    """`vidtrack trax ARGS` in a child process, spoken to over its stdin/stdout."""

    def __init__(self, *args, stderr_path):
        self.stderr = open(stderr_path, "w")
        self.process = subprocess.Popen([sys.executable, "-m", "vidtrack", "trax", *args], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=self.stderr, bufsize=0)
        # libtrax reads the server's messages from the child's stdout and writes to its stdin
        # (vot-trax 4.0.2's client needs a logger: log=False fails inside ctypes)
        self.log = []
        self.client = Client(stream=(self.process.stdin.fileno(), self.process.stdout.fileno()), timeout=60,
                             log=self.log.append)

    def initialize(self, path, box):
        objects, _ = self.client.initialize({"color": FileImage.create(str(path))},
                                            [(Rectangle.create(*box), {})], {})
        return self._answer(objects)

    def frame(self, path):
        objects, _ = self.client.frame({"color": FileImage.create(str(path))}, {}, [])
        return self._answer(objects)

    @staticmethod
    def _answer(objects):
        assert len(objects) == 1
        region, properties = objects[0]
        return tuple(region.bounds()), properties

    def close(self):
        self.client.quit()
        code = self.process.wait(timeout=60)
        self.stderr.close()
        return code


@pytest.fixture(scope="module")
def sequence():
    return load_sequence(SEQUENCES / SEQUENCE)


def drive(tracker, sequence, start, stop):
    """Boxes (0-based pixels) and properties of rows ``start..stop-1``, initialised on ``start``'s ground truth."""
    files = sequence.files
    init = sequence.to_pixels(sequence.ground_truth_box(start))
    answers = [tracker.initialize(files[start], (init.x, init.y, init.w, init.h))]
    answers += [tracker.frame(files[row]) for row in range(start + 1, stop)]
    return np.array([box for box, _ in answers]), [properties for _, properties in answers]


@needs_sequences()
@pytest.mark.parametrize("name", ["kalman-cv", "mil"])
def test_trax_boxes_equal_vidtrack_eval(name, sequence, tmp_path):
    assert main(["eval", str(SEQUENCES), "--filter", name, "--sequences", SEQUENCE, "--out", str(tmp_path / "eval"),
                 "--no-plots", "-q"]) == 0
    expected = np.array([sequence.to_pixels(Box(*row)).as_array()
                         for row in read_boxes(tmp_path / "eval" / name / f"{SEQUENCE}.txt")])

    tracker = TraxTracker("--filter", name, stderr_path=tmp_path / "stderr.txt")
    boxes, properties = drive(tracker, sequence, 0, len(sequence))
    assert tracker.close() == 0
    assert tracker.client.tracker_name == f"vidtrack-{name}"
    # eval writes 3 decimals; TraX carries float32
    np.testing.assert_allclose(boxes, expected, atol=2e-3)
    confidences = [float(p["confidence"]) for p in properties]
    assert all(0.0 <= c <= 1.0 for c in confidences) and confidences[0] == 1.0
    assert {p["status"] for p in properties} <= {"tracking", "lost"}


@needs_sequences()
def test_second_initialize_over_one_connection_starts_afresh(sequence, tmp_path):
    name = "mil"
    again = TraxTracker("--filter", name, stderr_path=tmp_path / "again.txt")
    drive(again, sequence, 0, 15)                  # track a while, then the client re-initialises
    second, _ = drive(again, sequence, 40, 55)
    assert again.close() == 0
    fresh = TraxTracker("--filter", name, stderr_path=tmp_path / "fresh.txt")
    alone, _ = drive(fresh, sequence, 40, 55)
    assert fresh.close() == 0
    np.testing.assert_array_equal(second, alone)


def test_bad_filter_is_one_line_and_exit_2(tmp_path):
    result = subprocess.run([sys.executable, "-m", "vidtrack", "trax", "--filter", "no-such"], capture_output=True,
                            text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert result.returncode == 2
    assert result.stderr.startswith("vidtrack: error: unknown filter 'no-such'") and result.stderr.count("\n") == 1
    assert result.stdout == ""


def test_unreadable_image_ends_the_session_with_one_line(tmp_path):
    tracker = TraxTracker("--filter", "kalman-cv", stderr_path=tmp_path / "stderr.txt")
    with pytest.raises(TraxException):
        tracker.initialize(tmp_path / "missing.jpg", (10, 10, 20, 20))
    assert tracker.process.wait(timeout=60) == 2
    tracker.stderr.close()
    lines = (tmp_path / "stderr.txt").read_text().splitlines()
    assert lines == [f"vidtrack: error: cannot decode image {tmp_path / 'missing.jpg'}: no such file"]


class RawClient:
    """`vidtrack trax --filter kalman-cv` spoken to with raw bytes over its stdin/stdout."""

    def __init__(self, tmp_path):
        import cv2

        self.image = tmp_path / "frame one.png"   # a space, as a path may have
        cv2.imwrite(str(self.image), np.full((60, 80, 3), 90, np.uint8))
        self.process = subprocess.Popen([sys.executable, "-m", "vidtrack", "trax", "--filter", "kalman-cv"],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert self.process.stdout.readline().startswith(b"@@TRAX:hello ")

    def send(self, data: bytes) -> None:
        self.process.stdin.write(data)
        self.process.stdin.flush()

    def initialize(self) -> bytes:
        # what the reference client sends: the region, then the image
        self.send(b'@@TRAX:initialize "10,10,20,20" \n@@TRAX:frame "file://' + str(self.image).encode() + b'" \n')
        return self.process.stdout.readline()

    def end(self, timeout: float = 30.0) -> tuple[int, list[str]]:
        """Exit code and stderr lines; fails (and kills the server) if it has not ended by ``timeout``."""
        deadline = time.monotonic() + timeout
        while self.process.poll() is None:
            if time.monotonic() > deadline:
                self.process.kill()
                raise AssertionError("the TraX server hung")
            time.sleep(0.05)
        return self.process.returncode, self.process.stderr.read().decode().splitlines()


@pytest.mark.parametrize("message,reason", [
    (b"hello there\n", "not a TraX message: 'hello there'"),
    (b"@@TRAX:frobnicate 1 2\n", "a client may not send 'frobnicate' (only initialize, frame, quit)"),
    (b'@@TRAX:initialize "1,2,3" \n@@TRAX:frame "file:///nowhere.png" \n', "malformed 'frame' message"),
])
def test_a_malformed_message_is_one_line_and_exit_2(tmp_path, message, reason):
    client = RawClient(tmp_path)
    client.send(message)   # the pipe stays open: the server must not wait for more
    code, lines = client.end()
    assert (code, lines) == (2, [f"vidtrack: error: TraX protocol error: {reason}"])
    assert client.process.stdout.read().startswith(b"@@TRAX:quit")


@pytest.mark.parametrize("cut", ["between messages", "mid-message"])
def test_a_client_that_disconnects_is_one_line_and_exit_1(tmp_path, cut):
    client = RawClient(tmp_path)
    assert client.initialize().startswith(b'@@TRAX:state "10.0000,10.0000,20.0000,20.0000"')
    if cut == "mid-message":
        client.send(b'@@TRAX:frame "file://' + str(client.image).encode()[:5])
    client.process.stdin.close()
    code, lines = client.end()
    where = " in the middle of a message" if cut == "mid-message" else ""
    assert (code, lines) == (1, [f"vidtrack: error: TraX client disconnected{where} after 1 frame without quitting"])


def test_a_client_that_stops_reading_is_one_line_and_exit_1(tmp_path):
    client = RawClient(tmp_path)
    client.process.stdout.close()   # the client's end of the server's replies is gone, its requests still open
    client.send(b'@@TRAX:initialize "10,10,20,20" \n@@TRAX:frame "file://' + str(client.image).encode() + b'" \n')
    code, lines = client.end()
    assert (code, lines) == (1, ["vidtrack: error: TraX client disconnected after 1 frame without quitting"])


def test_an_image_that_vanishes_mid_session_is_one_line_and_exit_2(tmp_path):
    client = RawClient(tmp_path)
    assert client.initialize().startswith(b"@@TRAX:state ")
    client.image.unlink()
    client.send(b'@@TRAX:frame "file://' + str(client.image).encode() + b'" \n')
    code, lines = client.end()
    assert (code, lines) == (2, [f"vidtrack: error: cannot decode image {client.image}: no such file"])
    assert client.process.stdout.readline().startswith(b'@@TRAX:quit "trax.reason=cannot decode image')
