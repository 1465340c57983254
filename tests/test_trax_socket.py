"""`vidtrack trax` over a local socket (`TRAX_SOCKET`, 127.0.0.1) driven by the VOT toolkit's own TraX client
library (its venv, `make vot-env`): the same boxes as over stdin/stdout, and a client that goes away part-way;
and `--trax-log` after a malformed message or a lost client (exit 2 or 1, no crash, a readable log)."""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from vidtrack.eval.datasets import load_sequence

from conftest import SEQUENCES, needs_sequences

VOT = os.environ.get("VIDTRACK_VOT")
needs_vot = pytest.mark.skipif(not VOT or not Path(VOT).is_file(),
                               reason="VOT toolkit venv not given (make test sets VIDTRACK_VOT from `make vot-env`)")
SEQUENCE = "Football1"
FRAMES = 12

#: A TraX client in the toolkit's venv.  argv[1]: JSON {"stream": listening socket fd | [to-server fd,
#: from-server fd], "files", "box", "stop_after": frames before it exits without quitting (or null)}.
#: Prints the boxes answered, one JSON list.
CLIENT = """
import json, os, sys
from trax.client import Client
from trax.image import FileImage
from trax.region import Rectangle

job = json.loads(sys.argv[1])
stream = job["stream"] if isinstance(job["stream"], int) else tuple(job["stream"])
client = Client(stream=stream, timeout=30, log=lambda message: None)
boxes = []
for row, path in enumerate(job["files"]):
    if row == job["stop_after"]:
        print(json.dumps(boxes), flush=True)
        os._exit(0)   # gone without a quit: the kernel closes the connection
    image = {"color": FileImage.create(path)}
    if row == 0:
        objects, _ = client.initialize(image, [(Rectangle.create(*job["box"]), {})], {})
    else:
        objects, _ = client.frame(image, {}, [])
    boxes.append(list(objects[0][0].bounds()))
client.quit()
print(json.dumps(boxes), flush=True)
"""


def wait_for(process, timeout=30.0):
    """``process``'s exit code; kills it and fails if it has not ended by ``timeout`` (a hang)."""
    try:
        return process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        raise AssertionError("the TraX server hung") from None


def serve_and_drive(transport, tmp_path, files, box, *server_args, stop_after=None):
    """Run `vidtrack trax --filter mil` over ``transport`` and the toolkit's client on ``files``.

    Returns the client's boxes, the server's exit code and its stderr lines.
    """
    stderr_path = tmp_path / f"{transport}-stderr.txt"
    command = [sys.executable, "-m", "vidtrack", "trax", "--filter", "mil", *server_args]
    with open(stderr_path, "w") as stderr:
        if transport == "socket":
            listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            listener.bind(("127.0.0.1", 0))   # a free port, on this machine only
            listener.listen(1)
            env = dict(os.environ, TRAX_SOCKET=str(listener.getsockname()[1]))
            server = subprocess.Popen(command, env=env, cwd=tmp_path, stdin=subprocess.DEVNULL,
                                      stdout=subprocess.PIPE, stderr=stderr)
            stream, passed = listener.fileno(), [listener.fileno()]
        else:
            listener = None
            server = subprocess.Popen(command, cwd=tmp_path, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      stderr=stderr, bufsize=0)
            stream = [server.stdin.fileno(), server.stdout.fileno()]
            passed = stream
        job = {"stream": stream, "files": [str(f) for f in files], "box": list(box), "stop_after": stop_after}
        try:
            client = subprocess.run([str(Path(VOT).parent / "python"), "-c", CLIENT, json.dumps(job)],
                                    pass_fds=passed, capture_output=True, text=True, timeout=120)
        finally:
            if listener is not None:
                listener.close()
            if server.stdin is not None:
                server.stdin.close()
        code = wait_for(server)
        leftover = server.stdout.read()
        server.stdout.close()
    assert client.returncode == 0, client.stderr
    if transport == "socket":
        assert leftover == b""   # over a socket nothing at all goes to stdout
    return np.array(json.loads(client.stdout)), code, stderr_path.read_text().splitlines()


@pytest.fixture(scope="module")
def sequence():
    return load_sequence(SEQUENCES / SEQUENCE)


def first_frames(sequence, count):
    init = sequence.to_pixels(sequence.ground_truth_box(0))
    return sequence.files[:count], (init.x, init.y, init.w, init.h)


@needs_vot
@needs_sequences()
def test_socket_transport_answers_as_stdin_stdout_does(sequence, tmp_path):
    files, box = first_frames(sequence, FRAMES)
    over_socket, code, lines = serve_and_drive("socket", tmp_path, files, box)
    assert (code, lines) == (0, [])
    over_pipes, code, lines = serve_and_drive("pipes", tmp_path, files, box)
    assert (code, lines) == (0, [])
    assert over_socket.shape == (FRAMES, 4)
    np.testing.assert_array_equal(over_socket[0], box)
    np.testing.assert_array_equal(over_socket, over_pipes)
    assert len(np.unique(over_socket[:, :2], axis=0)) > 1   # the tracker moved: real answers, not the init box


@needs_vot
@needs_sequences()
def test_socket_client_gone_mid_run_is_one_line_and_exit_1(sequence, tmp_path):
    files, box = first_frames(sequence, FRAMES)
    started = time.monotonic()
    boxes, code, lines = serve_and_drive("socket", tmp_path, files, box, "--trax-log", "trax.log", stop_after=4)
    assert len(boxes) == 4
    assert (code, lines) == (1, ["vidtrack: error: TraX client disconnected after 4 frames without quitting"])
    assert time.monotonic() - started < 60
    log = (tmp_path / "trax.log").read_text().splitlines()   # relative to the server's folder
    assert log[0].startswith("@@TRAX:hello ") and sum(line.startswith("@@TRAX:state ") for line in log) == 4


@pytest.mark.parametrize("cut", ["after a frame", "mid-message"])
def test_socket_closed_by_a_raw_client_is_one_line_and_exit_1(tmp_path, cut):
    """The client's socket closes while the server computes a reply, or in the middle of a message."""
    import cv2

    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), np.full((60, 80, 3), 90, np.uint8))
    message = f'@@TRAX:initialize "10,10,20,20" \n@@TRAX:frame "file://{image}" \n'.encode()
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)
        listener.settimeout(60)
        env = dict(os.environ, TRAX_SOCKET=str(listener.getsockname()[1]))
        server = subprocess.Popen([sys.executable, "-m", "vidtrack", "trax", "--filter", "kalman-cv"], env=env,
                                  stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        connection, _ = listener.accept()
        with connection:
            assert connection.recv(7) == b"@@TRAX:"
            connection.sendall(message if cut == "after a frame" else message[:40])
    code = wait_for(server)
    frames = "1 frame" if cut == "after a frame" else "0 frames"
    assert server.stderr.read().decode().splitlines() == [
        f"vidtrack: error: TraX client disconnected after {frames} without quitting"]
    assert code == 1 and server.stdout.read() == b""


MALFORMED = b'@@TRAX:initialize "1,2,3" \n@@TRAX:frame "file:///nowhere.png" \n'


def test_malformed_message_with_trax_log_is_exit_2_and_a_readable_log(tmp_path):
    log = tmp_path / "logs dir" / "trax.log"   # a folder that does not exist yet, with a space
    server = subprocess.Popen([sys.executable, "-m", "vidtrack", "trax", "--filter", "kalman-cv", "--trax-log",
                               str(log)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert server.stdout.readline().startswith(b"@@TRAX:hello ")
    server.stdin.write(MALFORMED)   # the pipe stays open: the server must not wait for more
    server.stdin.flush()
    code = wait_for(server)
    server.stdin.close()
    assert code == 2   # not -11: libtrax's last log line went to a live logger
    assert server.stderr.read().decode().splitlines() == [
        "vidtrack: error: TraX protocol error: malformed 'frame' message"]
    assert server.stdout.read().startswith(b"@@TRAX:quit")
    lines = log.read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("@@TRAX:hello ") and '@@TRAX:initialize "1,2,3" ' in lines
    assert lines[-1].startswith("@@TRAX:quit")


def test_unwritable_trax_log_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "file").write_text("")
    result = subprocess.run([sys.executable, "-m", "vidtrack", "trax", "--trax-log", str(tmp_path / "file" / "log")],
                            capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert result.returncode == 2
    lines = result.stderr.splitlines()   # its folder cannot be made: a file has that name
    assert len(lines) == 1 and lines[0].startswith(f"vidtrack: error: cannot write {tmp_path / 'file' / 'log'}: ")
    assert result.stdout == ""
