"""Paths, with real child processes of ``python -m vidtrack``.

Spaces and non-ASCII characters in the video, frame-folder, output and
dataset paths; output folders that do not exist yet (created, with their
parents); a read-only output folder (one line, exit 2, nothing written).
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from hard_stop_helpers import mounted_tmpfs, square_frame, square_position, write_frames  # noqa: E402

from vidtrack.eval.datasets import read_boxes  # noqa: E402
from vidtrack.sinks.h264 import count_frames  # noqa: E402

FRAMES = 12


def _video(path: Path, count: int) -> Path:
    from vidtrack.sinks.h264 import H264Writer

    path.parent.mkdir(parents=True, exist_ok=True)
    writer = H264Writer(path, fps=30.0, batch=10)
    for index in range(count):
        writer.write(square_frame(index))
    writer.close()
    return path


def _start(args: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "vidtrack", *args], cwd=cwd, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(process: subprocess.Popen) -> tuple[int, str]:
    try:
        _, stderr = process.communicate(timeout=180)
    except subprocess.TimeoutExpired:
        process.kill()
        process.communicate()
        raise AssertionError("vidtrack did not end") from None
    return process.returncode, stderr


def _track_args(source: Path) -> list[str]:
    x, y = square_position(0)
    return [str(source), "--init-box", f"{x},{y},16,16", "--filter", "kalman-cv", "-q"]


def _dataset(root: Path, names: tuple[str, ...]) -> Path:
    for name in names:
        folder = write_frames(root / name / "img", FRAMES)
        rows = [f"{x + 1},{y + 1},16,16" for x, y in (square_position(i) for i in range(FRAMES))]
        (folder.parent / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root


def test_non_ascii_and_spaced_paths_for_every_input_and_output(tmp_path):
    from rerun_reader import read_recording

    inputs = {"video": _video(tmp_path / "dossier été" / "vidéo 1.mp4", FRAMES),
              "folder": write_frames(tmp_path / "dossier été" / "данные кадры", FRAMES)}
    runs = {}
    for kind, source in inputs.items():
        out = tmp_path / "sortie é" / "новая папка" / kind       # none of these folders exist yet
        paths = {"-o": out / "vidéo annotée.mp4", "--boxes": out / "boîtes 1.txt", "--log": out / "журнал.csv",
                 "--rerun": out / "enregistrement ü.rrd"}
        options = [part for option, path in paths.items() for part in (option, str(path))]
        runs[kind] = (_start(_track_args(source) + options, tmp_path), paths)
    data = _dataset(tmp_path / "données été", ("Séquence une", "Вторая"))
    results, recordings = tmp_path / "résultats" / "новые" / "out", tmp_path / "résultats" / "rerun дир"
    evaluation = _start(["eval", str(data), "--filter", "kalman-cv", "--no-plots", "-q", "--out", str(results),
                         "--rerun", str(recordings)], tmp_path)

    for kind, (process, paths) in runs.items():
        code, stderr = _finish(process)
        assert code == 0 and stderr == "", (kind, stderr)
        assert len(read_boxes(paths["--boxes"])) == FRAMES
        with open(paths["--log"], newline="", encoding="utf-8") as file:
            assert [int(row[0]) for row in list(csv.reader(file))[1:]] == list(range(FRAMES))
        assert count_frames(paths["-o"]) == FRAMES                        # PyAV reads it
        assert read_recording(paths["--rerun"])["video/frame"] == list(range(FRAMES))

    code, stderr = _finish(evaluation)
    assert code == 0 and "Traceback" not in stderr, stderr
    for name in ("Séquence une", "Вторая"):
        assert len(read_boxes(results / "kalman-cv" / f"{name}.txt")) == FRAMES
        assert read_recording(recordings / "kalman-cv" / f"{name}.rrd")["video/frame"] == list(range(FRAMES))


@pytest.fixture(params=["chmod", "read-only mount"])
def read_only_folder(request, tmp_path):
    """A folder nothing can be written in: ``chmod 555`` (as a user), or a read-only tmpfs (as root, whom
    permissions do not stop)."""
    folder = tmp_path / "lecture seule"
    folder.mkdir()
    root = os.geteuid() == 0
    if request.param == "chmod":
        if root:
            pytest.skip("root writes into a chmod 555 folder anyway; the read-only mount case covers root")
        folder.chmod(0o555)
        yield folder
        folder.chmod(0o755)
        return
    yield from mounted_tmpfs(folder, "64k", read_only=True, exist_ok=True)


def test_a_read_only_output_folder_is_one_line_and_exit_2(tmp_path, read_only_folder):
    source = write_frames(tmp_path / "img", FRAMES)
    data = _dataset(tmp_path / "data", ("Alpha",))
    cases = {  # each output kind opens its file its own way: the video, a text file, the recording
        "-o": _track_args(source) + ["-o", str(read_only_folder / "out.mp4")],
        "--boxes": _track_args(source) + ["--boxes", str(read_only_folder / "b.txt")],
        "--rerun": _track_args(source) + ["--rerun", str(read_only_folder / "r.rrd")],
        "--log in a missing folder": _track_args(source) + ["--log", str(read_only_folder / "new" / "l.csv")],
        "eval --out": ["eval", str(data), "--filter", "kalman-cv", "-q", "--out", str(read_only_folder / "out")],
        "eval --rerun": ["eval", str(data), "--filter", "kalman-cv", "-q", "--out", str(tmp_path / "results"),
                         "--rerun", str(read_only_folder)],
    }
    started = {case: _start(args, tmp_path) for case, args in cases.items()}
    for case, process in started.items():
        code, stderr = _finish(process)
        assert code == 2, (case, code, stderr)
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"vidtrack: error: cannot write {read_only_folder}"), \
            (case, stderr)
        assert lines[0].endswith(("Read-only file system", "Permission denied")), (case, stderr)
    assert not list(read_only_folder.iterdir())
    assert not (tmp_path / "results").exists() or not list((tmp_path / "results").rglob("*.txt"))


@pytest.fixture
def small_disk(tmp_path):
    """A 256 KB tmpfs folder with a space in its name (mounted for the test: needs root)."""
    yield from mounted_tmpfs(tmp_path / "petit disque", "256k")


def test_a_full_disk_under_the_recording_is_one_line_exit_1_and_keeps_every_complete_batch(tmp_path, square_frames,
                                                                                            small_disk):
    import re

    from rerun_reader import read_recording

    source = write_frames(tmp_path / "img", 2000, square_frames)
    recording, boxes = small_disk / "r é.rrd", tmp_path / "b.txt"
    process = _start(_track_args(source) + ["--flush-every", "10", "--rerun", str(recording), "--boxes", str(boxes)],
                     tmp_path)
    code, stderr = _finish(process)
    assert code == 1, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    assert lines[0].startswith(f"vidtrack: error: cannot write {recording}: No space left on device"), stderr
    written = int(re.search(r"keep the (\d+) frames", lines[0]).group(1))
    assert 0 < written < 2000 and written <= len(read_boxes(boxes)) <= written + 1   # the failing frame too
    with warnings.catch_warnings():                          # rerun warns that the footer is missing
        warnings.simplefilter("ignore")
        frames = read_recording(recording)["video/frame"]     # readable: cut back to its last complete batch
    assert frames == list(range(len(frames))) and len(frames) % 10 == 0 and written - 10 < len(frames) <= written
