"""Exports: CVAT for video 1.1, MOT Challenge and JSON lines, read back by Datumaro and after a hard stop.

The independent reader is Datumaro (``tests/datumaro_reader.py``) in a venv
of its own (``make datumaro-env``; ``make test`` sets ``VIDTRACK_DATUMARO``
to its Python).  Without it those tests skip with the reason.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from vidtrack.errors import OutputError, UsageError
from vidtrack.sinks.exports import EXPORT_FORMATS, export_format, open_export
from vidtrack.types import Box, Frame, TrackState

HERE = Path(__file__).parent
FRAMES = 40
SIZE = (64, 48)
HALF_CENT = 0.005 + 1e-6   # boxes are written with 2 decimals


def _run() -> list[dict[int, TrackState]]:
    """Three targets over 40 frames: 1 throughout (lost on frames 10-14), 2 from frame 5 to 29, 3 from 20.

    Boxes move by fractions of a pixel, so rounding would show.
    """
    rng = np.random.default_rng(0)
    frames = []
    for k in range(FRAMES):
        targets = {}
        spans = {1: (0, FRAMES), 2: (5, 30), 3: (20, FRAMES)}
        for target_id, (first, stop) in spans.items():
            if first <= k < stop:
                x, y = rng.uniform(0, 40, 2).round(3)
                w, h = rng.uniform(4, 20, 2).round(3)
                lost = target_id == 1 and 10 <= k < 15
                targets[target_id] = TrackState(k, Box(float(x), float(y), float(w), float(h)),
                                                round(float(rng.uniform(0, 1)), 4), "lost" if lost else "tracking")
        frames.append(targets)
    return frames


def _write(path: Path, fmt: str, run: list[dict[int, TrackState]], **kw) -> None:
    image = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    sink = open_export(path, fmt, filter_name="kalman-cv", **kw)
    for k, targets in enumerate(run):
        sink.write(Frame(k, image), targets)
    sink.close()


def test_format_by_extension_or_named():
    assert export_format("a/b.xml") == "cvat" and export_format("B.XML") == "cvat"
    assert export_format("run.txt") == "mot" and export_format("run.jsonl") == "jsonl"
    assert export_format("run.dat", "mot") == "mot"            # the named format wins over the name
    assert EXPORT_FORMATS == ("cvat", "mot", "jsonl")
    with pytest.raises(UsageError, match=r"\.xml \(cvat\).*--export-format"):
        export_format("run.csv")
    with pytest.raises(UsageError, match="choose one of cvat, mot, jsonl"):
        export_format("run.xml", "yolo")
    with pytest.raises(UsageError):
        open_export("run.xml", "yolo")


@pytest.mark.parametrize("fmt", EXPORT_FORMATS)
def test_unwritable_path_is_one_clear_error(tmp_path, fmt):
    with pytest.raises(OutputError, match="it is a folder"):
        open_export(tmp_path, fmt)


def test_jsonl_and_mot_lines(tmp_path):
    run = _run()
    _write(tmp_path / "run.jsonl", "jsonl", run)
    _write(tmp_path / "run.txt", "mot", run)
    rows = [json.loads(line) for line in (tmp_path / "run.jsonl").read_text().splitlines()]
    expected = [(k, i, s) for k, targets in enumerate(run) for i, s in sorted(targets.items())]
    assert len(rows) == len(expected)
    for row, (k, target_id, state) in zip(rows, expected):
        assert set(row) == {"frame", "id", "box", "confidence", "status"}
        assert (row["frame"], row["id"], row["status"]) == (k, target_id, state.status)
        assert row["box"] == pytest.approx(state.box.as_array(), abs=HALF_CENT)
        assert row["confidence"] == pytest.approx(state.confidence, abs=1e-4)
    lines = (tmp_path / "run.txt").read_text().splitlines()
    assert len(lines) == len(expected)
    for line, (k, target_id, state) in zip(lines, expected):
        fields = line.split(",")
        assert len(fields) == 10 and fields[7:] == ["-1", "-1", "-1"]
        assert (int(fields[0]), int(fields[1])) == (k + 1, target_id)         # MOT frames are 1-based
        assert [float(v) for v in fields[2:6]] == pytest.approx(state.box.as_array(), abs=HALF_CENT)
        assert float(fields[6]) == pytest.approx(state.confidence, abs=1e-4)


def test_cvat_document(tmp_path):
    run = _run()
    _write(tmp_path / "run.xml", "cvat", run)
    root = ET.parse(tmp_path / "run.xml").getroot()
    assert root.tag == "annotations" and root.findtext("version") == "1.1"
    task = root.find("meta/task")
    assert task.findtext("size") == str(FRAMES) and task.findtext("mode") == "interpolation"
    assert (task.findtext("original_size/width"), task.findtext("original_size/height")) == ("64", "48")
    assert [label.findtext("name") for label in task.iter("label")] == ["target"]
    assert "kalman-cv" in task.findtext("name")
    tracks = {int(t.get("id")): t for t in root.iter("track")}
    assert sorted(tracks) == [1, 2, 3] and {t.get("label") for t in tracks.values()} == {"target"}
    for target_id, track in tracks.items():
        boxes = {int(b.get("frame")): b for b in track.iter("box")}
        seen = [k for k, targets in enumerate(run) if target_id in targets]
        for k in seen:
            state, box = run[k][target_id], boxes[k]
            x, y, w, h = state.box.as_array()
            assert [float(box.get(a)) for a in ("xtl", "ytl", "xbr", "ybr")] == pytest.approx(
                [x, y, x + w, y + h], abs=HALF_CENT)
            assert box.get("outside") == ("1" if state.status == "lost" else "0")
            assert box.get("keyframe") == "1" and box.get("occluded") == "0"
        # a target that leaves gets an outside box on the first frame it is missing, ending its track there
        extra = sorted(set(boxes) - set(seen))
        assert extra == ([30] if target_id == 2 else [])
        if extra:
            assert boxes[30].get("outside") == "1"


def _datumaro() -> str:
    python = os.environ.get("VIDTRACK_DATUMARO")
    if not python:
        pytest.skip("VIDTRACK_DATUMARO is not set (make test sets it to the Python of `make datumaro-env`)")
    if not Path(python).is_file():
        pytest.skip(f"VIDTRACK_DATUMARO={python} does not exist (run `make datumaro-env`)")
    return python


def test_datumaro_reads_every_box_and_id(tmp_path):
    python = _datumaro()
    run = _run()
    _write(tmp_path / "run.xml", "cvat", run)
    _write(tmp_path / "run.txt", "mot", run)
    done = subprocess.run([python, str(HERE / "datumaro_reader.py"), "--cvat", str(tmp_path / "run.xml"),
                           "--mot", str(tmp_path / "run.txt")], capture_output=True, text=True, timeout=120,
                          env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert done.returncode == 0, done.stderr
    read = json.loads(done.stdout)
    expected = sorted(((target_id, k, state) for k, targets in enumerate(run) for target_id, state in targets.items()),
                      key=lambda e: (e[0], e[1]))

    # CVAT: every box of every track, its ID and outside flag; plus track 2's closing outside box
    cvat = {(r["track_id"], r["frame"]): r for r in read["cvat"]}
    assert set(cvat) == {(i, k) for i, k, _ in expected} | {(2, 30)}
    for target_id, k, state in expected:
        row = cvat[(target_id, k)]
        assert row["label"] == "target" and row["keyframe"] is True
        assert row["outside"] is (state.status == "lost")
        assert row["box"] == pytest.approx(state.box.as_array(), abs=0.011)   # corners to 2 decimals
    assert cvat[(2, 30)]["outside"] is True

    # MOT: every line, 1-based frames, the ID and the confidence as Datumaro's score
    mot = {(r["track_id"], r["frame"]): r for r in read["mot"]}
    assert set(mot) == {(i, k + 1) for i, k, _ in expected}
    for target_id, k, state in expected:
        row = mot[(target_id, k + 1)]
        assert row["box"] == pytest.approx(state.box.as_array(), abs=0.006)
        assert row["score"] == pytest.approx(state.confidence, abs=1e-4)


_KILLED_WRITER = textwrap.dedent("""
    import os, signal, sys, time
    import numpy as np
    from vidtrack.sinks.exports import open_export
    from vidtrack.types import Box, Frame, TrackState

    out, stop, batch = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    sinks = [open_export(os.path.join(out, name), fmt, batch=batch)
             for name, fmt in (("run.xml", "cvat"), ("run.txt", "mot"), ("run.jsonl", "jsonl"))]
    image = np.zeros((48, 64, 3), np.uint8)
    for k in range(10 ** 6):
        if k == stop:
            os.kill(os.getpid(), signal.SIGKILL)      # a hard stop: no close, no flush, no handler
        targets = {i: TrackState(k, Box(k % 30 + i, 10.5, 8, 9), 0.5, "lost" if k % 7 == 0 else "tracking")
                   for i in (1, 2)}
        for sink in sinks:
            sink.write(Frame(k, image), targets)
        time.sleep(0.02)                            # a tracker's time per frame: a rewrite costs far less
""")


def test_hard_stop_keeps_every_line_and_the_xml_up_to_its_last_rewrite(tmp_path):
    stop, batch = 137, 20
    done = subprocess.run([sys.executable, "-c", _KILLED_WRITER, str(tmp_path), str(stop), str(batch)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == -9, done.stderr
    jsonl = [json.loads(line) for line in (tmp_path / "run.jsonl").read_text().splitlines()]
    assert [(r["frame"], r["id"]) for r in jsonl] == [(k, i) for k in range(stop) for i in (1, 2)]
    mot = (tmp_path / "run.txt").read_text().splitlines()
    assert [tuple(map(int, line.split(",")[:2])) for line in mot] == [(k + 1, i) for k in range(stop) for i in (1, 2)]
    root = ET.parse(tmp_path / "run.xml").getroot()                 # a complete document
    frames = [sorted(int(b.get("frame")) for b in track.iter("box")) for track in root.iter("track")]
    assert len(frames) == 2 and frames[0] == frames[1] == list(range(len(frames[0])))
    assert stop - batch <= len(frames[0]) <= stop, len(frames[0])
    assert int(root.findtext("meta/task/size")) == len(frames[0])
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_a_failed_rewrite_keeps_the_last_document(tmp_path, monkeypatch):
    """A full disk during a rewrite: WriteFailed, the file stays the last complete document, no temporary left."""
    import errno

    from vidtrack.sinks import exports
    from vidtrack.sinks.base import WriteFailed

    run = _run()
    image = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    sink = open_export(tmp_path / "run.xml", "cvat", batch=1)
    for k in range(5):
        sink.write(Frame(k, image), run[k])
    sink.flush()                                        # a rewrite with these 5 frames
    before = (tmp_path / "run.xml").read_bytes()
    sink.write(Frame(5, image), run[5])

    def full(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(exports.os, "replace", full)
    with pytest.raises(WriteFailed, match="No space left"):
        sink.flush()                                    # the rewrite with frame 5 fails
    assert (tmp_path / "run.xml").read_bytes() == before
    assert ET.fromstring(before).find("meta/task/size").text == "5"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.xml"]


@pytest.mark.parametrize("fmt,name", [("cvat", "run.xml"), ("mot", "run.txt"), ("jsonl", "run.jsonl")])
def test_a_single_state_is_target_1(tmp_path, fmt, name):
    image = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    state = TrackState(0, Box(1, 2, 3, 4), 0.5, "tracking")
    for folder, targets in (("single", state), ("mapping", {1: state})):
        (tmp_path / folder).mkdir()
        sink = open_export(tmp_path / folder / name, fmt)
        sink.write(Frame(0, image), targets)
        sink.close()
    assert (tmp_path / "single" / name).read_bytes() == (tmp_path / "mapping" / name).read_bytes()


@pytest.mark.parametrize("suffix, fmt", [(".xml", None), (".jsonl", None), (".out", "mot")])
def test_command_line_export_of_two_targets(tmp_path, suffix, fmt):
    """``vidtrack VIDEO --init-box A --init-box B --export FILE``: every frame of both targets, as the boxes say."""
    from conftest import SAMPLE_VIDEO

    from vidtrack.cli import main

    export = tmp_path / f"run{suffix}"
    boxes = tmp_path / "boxes.txt"
    argv = [str(SAMPLE_VIDEO), "--init-box", "56,20,31,45", "--init-box", "10,10,20,20", "--filter", "kalman-cv",
            "--max-frames", "12", "--boxes", str(boxes), "--export", str(export), "-q"]
    assert main(argv + (["--export-format", fmt] if fmt else [])) == 0
    mot = [line.split(",") for line in boxes.read_text().splitlines()]
    expected = {(int(r[0]) - 1, int(r[1])): [float(v) for v in r[2:6]] for r in mot}
    assert len(expected) == 24
    if suffix == ".xml":
        tracks = ET.parse(export).getroot().findall("track")
        assert sorted(int(t.get("id")) for t in tracks) == [1, 2]
        got = {(int(b.get("frame")), int(t.get("id"))): [float(b.get(k)) for k in ("xtl", "ytl", "xbr", "ybr")]
               for t in tracks for b in t.findall("box") if b.get("outside") == "0"}
        got = {k: [x0, y0, x1 - x0, y1 - y0] for k, (x0, y0, x1, y1) in got.items()}
    elif suffix == ".jsonl":
        rows = [json.loads(line) for line in export.read_text().splitlines()]
        got = {(r["frame"], r["id"]): r["box"] for r in rows}
    else:
        got = {(int(r[0]) - 1, int(r[1])): [float(v) for v in r[2:6]]
               for r in (line.split(",") for line in export.read_text().splitlines())}
    assert set(got) <= set(expected) and len(got) >= 20
    for key, box in got.items():
        np.testing.assert_allclose(box, expected[key], atol=0.01)


def test_command_line_export_with_an_unknown_extension_is_one_line(tmp_path, capsys):
    from conftest import SAMPLE_VIDEO

    from vidtrack.cli import main

    code = main([str(SAMPLE_VIDEO), "--init-box", "56,20,31,45", "--export", str(tmp_path / "run.csv"), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "export" in err[0]
    assert not (tmp_path / "run.csv").exists()
