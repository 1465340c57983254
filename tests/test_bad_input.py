"""A corpus of bad input over every command: one line on stderr, exit 2, no traceback, no half file.

Each case runs the real entry point (``vidtrack.cli.main``, as the console
script does) on files made here; outputs go to ``OUT/``, which must stay
empty: bad input never leaves an empty or half-written file behind.
"""

from __future__ import annotations

import os
import wave
from pathlib import Path

import cv2
import numpy as np
import pytest

from vidtrack.cli import main

from conftest import SAMPLE_VIDEO
from live_helpers import FileServer, closed_port

#: (argv with {placeholders}, text the one error line must contain).  Placeholders: files made
#: by :func:`corpus_files`; {out} is the folder that must stay empty.
CASES: dict[str, tuple[list[str], str]] = {
    # -- vidtrack VIDEO: the input
    "missing video": (["nope.mp4", "--init-box", "1,1,5,5"], "no such"),
    "folder without images": (["{empty}", "--init-box", "1,1,5,5"], "no images"),
    "random bytes as mp4": (["{random}", "--init-box", "1,1,5,5"], "cannot decode"),
    "zero-byte file": (["{zero}", "--init-box", "1,1,5,5"], "cannot decode"),
    "text file as video": (["{text}", "--init-box", "56,20,31,45"], "not a video file"),
    "short text file as video": (["{short_text}", "--init-box", "56,20,31,45"], "cannot decode video"),
    "text file named .mp4": (["{text_mp4}", "--init-box", "56,20,31,45"], "cannot decode video"),
    "video without frames": (["{no_frames}", "--init-box", "1,1,5,5"], "no decodable frame"),
    "audio only": (["{audio}", "--init-box", "1,1,5,5"], "no video stream"),
    "lyrics file named .mp4": (["{lyrics}", "--init-box", "1,1,5,5"], "no video stream"),
    "mixed image sizes": (["{mixed}", "--init-box", "1,1,5,5"], "0002.png is 80x60"),
    "image folder with a broken first image": (["{broken_first}", "--init-box", "1,1,5,5"], "cannot decode image"),
    # -- the box
    "malformed box": (["{video}", "--init-box", "1,2,three,4"], "four numbers"),
    "three numbers": (["{video}", "--init-box", "1,2,3"], "four numbers"),
    "five numbers": (["{video}", "--init-box", "1,2,3,4,5"], "four numbers"),
    "empty box": (["{video}", "--init-box", ""], "four numbers"),
    "NaN in box": (["{video}", "--init-box", "nan,20,31,45"], "finite"),
    "inf in box": (["{video}", "--init-box", "56,20,inf,45"], "finite"),
    "zero size": (["{video}", "--init-box", "10,10,0,5"], "positive"),
    "negative size": (["{video}", "--init-box", "10,10,5,-5"], "positive"),
    "box outside": (["{video}", "--init-box", "1000,1000,20,20"], "outside"),
    "box mostly left of the frame": (["{video}", "--init-box", "-30,20,31,45"], "outside"),
    "box 1e9 wide": (["{video}", "--init-box", "0,0,1e9,45"], "outside"),
    "missing --init-box": (["{video}"], "init-box"),
    # -- several targets
    "--init-boxes with a bad line": (["{video}", "--init-boxes", "{boxes_bad}"], "boxes_bad.txt line 3: expected id,x,y,w,h"),
    "--init-boxes with a duplicate ID": (["{video}", "--init-boxes", "{boxes_duplicate}"],
                                         "line 3: target ID 2 is already on line 2"),
    "--init-boxes with ID 0": (["{video}", "--init-boxes", "{boxes_zero_id}"], "must be a positive integer"),
    "--init-boxes with a box of zero width": (["{video}", "--init-boxes", "{boxes_zero_width}"],
                                              "line 1 must have a positive width"),
    "--init-boxes missing": (["{video}", "--init-boxes", "nope.txt"], "cannot read --init-boxes nope.txt"),
    "--init-boxes empty": (["{video}", "--init-boxes", "{boxes_empty}"], "holds no id,x,y,w,h line"),
    "--init-boxes beside --init-box": (["{video}", "--init-box", "1,1,5,5", "--init-boxes", "{boxes_empty}"],
                                       "not allowed with argument"),
    "second --init-box outside": (["{video}", "--init-box", "56,20,31,45", "--init-box", "900,900,9,9"],
                                  "--init-box #2 900.00,900.00,9.00,9.00 lies outside"),
    "second --init-box malformed": (["{video}", "--init-box", "56,20,31,45", "--init-box", "1,2,3"],
                                    "--init-box #2 must be four numbers"),
    "--init-box without value": (["{video}", "--init-box"], "expected one argument"),
    # -- degenerate boxes for OpenCV's trackers (inside OpenCV: an assertion, a segfault or a hang)
    "opencv-csrt on 1x1": (["{video}", "--init-box", "56,20,1,1", "--filter", "opencv-csrt"], "at least 8x8"),
    "opencv-mosse on 1x1": (["{video}", "--init-box", "56,20,1,1", "--filter", "opencv-mosse"], "at least 8x8"),
    "opencv-mil on 1x1": (["{video}", "--init-box", "56,20,1,1", "--filter", "opencv-mil"], "at least 8x8"),
    "opencv-mil on the whole frame": (["{video}", "--init-box", "0,0,320,240", "--filter", "opencv-mil"],
                                      "background"),
    "opencv-tld on a 100x10 box": (["{video}", "--init-box", "10,10,100,10", "--filter", "opencv-tld"],
                                   "times longer"),
    "opencv-kcf on a sliver at the border": (["{video}", "--init-box", "314,0,10,50", "--filter", "opencv-kcf"],
                                             "at least 8x8"),
    # -- options
    "unknown filter": (["{video}", "--init-box", "1,1,5,5", "--filter", "nope"], "kalman-cv"),
    "option the filter does not take": (["{video}", "--init-box", "1,1,5,5", "--filter", "ms",
                                         "--detector", "face"], "filter ms: unknown option 'detector'"),
    "missing model file": (["{video}", "--init-box", "1,1,20,20", "--filter", "cbt", "--model", "nope.npz"],
                           "no such file"),
    "unknown option": (["{video}", "--init-box", "1,1,5,5", "--bogus"], "unrecognized"),
    "--max-frames 0": (["{video}", "--init-box", "1,1,5,5", "--max-frames", "0"], "at least 1"),
    "--flush-every 0": (["{video}", "--init-box", "1,1,5,5", "--flush-every", "0"], "at least 1"),
    "--seed not a number": (["{video}", "--init-box", "1,1,5,5", "--seed", "x"], "invalid int"),
    # -- tracker options: --set and --config
    "--set of an unknown option": (["{video}", "--init-box", "1,1,5,5", "--filter", "svk", "--set", "svr.D=1"],
                                   "filter svk: unknown option 'svr.D'; valid options: meanshift.bins,"),
    "--set of a group": (["{video}", "--init-box", "1,1,5,5", "--filter", "svk", "--set", "svr=1"],
                         "is a group"),
    "--set of a bad value": (["{video}", "--init-box", "1,1,5,5", "--filter", "svk", "--set", "svr.C=big"],
                             "bad value 'big' for option svr.C (float)"),
    "--set without =": (["{video}", "--init-box", "1,1,5,5", "--set", "bins"], "--set takes KEY=VALUE"),
    "--set of a tracker without it": (["{video}", "--init-box", "1,1,5,5", "--filter", "opencv-kcf",
                                       "--set", "scale_step=0.1"], "filter opencv-kcf: unknown option"),
    "missing --config file": (["{video}", "--init-box", "1,1,5,5", "--config", "nope.toml"],
                              "--config: no such file: nope.toml"),
    "--config not TOML": (["{video}", "--init-box", "1,1,5,5", "--config", "{bad_toml}"], "is not valid TOML"),
    "--config of a folder": (["{video}", "--init-box", "1,1,5,5", "--config", "{empty}"], "is a folder"),
    "--config with an unknown option": (["{video}", "--init-box", "1,1,5,5", "--filter", "kalman-cv",
                                         "--config", "{unknown_toml}"], "unknown option 'fusion.redetect'"),
    # -- outputs
    "unwritable boxes": (["{video}", "--init-box", "1,1,5,5", "--boxes", "/proc/vidtrack/b.txt"], "cannot write"),
    "unwritable video": (["{video}", "--init-box", "1,1,5,5", "-o", "/proc/vidtrack/o.mp4"], "cannot write"),
    "unwritable recording": (["{video}", "--init-box", "1,1,5,5", "--rerun", "/proc/vidtrack/r.rrd"],
                             "cannot write"),
    "boxes path is a folder": (["{video}", "--init-box", "1,1,5,5", "--boxes", "{empty}"], "it is a folder"),
    # -- vidtrack eval
    "eval: missing dataset": (["eval", "nope", "--filter", "kalman-cv"], "no such dataset"),
    "eval: folder without sequences": (["eval", "{empty}", "--filter", "kalman-cv"], "no sequences"),
    "eval: unknown filter": (["eval", "{dataset}", "--filter", "nope"], "unknown filter"),
    "eval: unknown sequence": (["eval", "{dataset}", "--filter", "kalman-cv", "--sequences", "Nope"],
                               "unknown sequence"),
    "eval: init box outside the frame": (["eval", "{gt_outside}", "--filter", "mil"], "row 1"),
    "eval: init box 1e9 wide": (["eval", "{gt_huge}", "--filter", "mil"], "lies outside the 64x48 frame"),
    "eval: ground-truth row of three numbers": (["eval", "{gt_three}", "--filter", "kalman-cv"],
                                                "expected 4 numbers"),
    "eval: ground truth longer than the images": (["eval", "{gt_long}", "--filter", "kalman-cv"], "4 rows"),
    "eval: nothing annotated": (["eval", "{gt_zero}", "--filter", "kalman-cv"], "no annotated"),
    "eval: images of two sizes": (["eval", "{gt_mixed}", "--filter", "kalman-cv"], "0001.png is 80x60"),
    "eval: --jobs 0": (["eval", "{dataset}", "--filter", "kalman-cv", "--jobs", "0"], "at least 1"),
    "eval: --max-frames 0": (["eval", "{dataset}", "--filter", "kalman-cv", "--max-frames", "0"], "at least 1"),
    "eval: an option one filter lacks": (["eval", "{dataset}", "--filter", "kalman-cv,opencv-kcf", "--out", "{out}/e",
                                          "--set", "scale_step=0.1"], "filter opencv-kcf: unknown option"),
    "eval: missing --config file": (["eval", "{dataset}", "--filter", "kalman-cv", "--config", "nope.toml"],
                                    "no such file"),
    # -- vidtrack learn
    "learn: unknown kind": (["learn", "foo", "{dataset}", "--out", "{out}/m.npz"], "invalid choice"),
    "learn: missing source": (["learn", "cbt", "nope", "--out", "{out}/m.npz"], "no such"),
    "learn: video without --init-box": (["learn", "cbt", "{video}", "--out", "{out}/m.npz"], "give --init-box"),
    "learn: --order 5": (["learn", "cbt", "{dataset}", "--out", "{out}/m.npz", "--order", "5"], "1, 2 or 3"),
    "learn: box outside the video": (["learn", "cbt", "{video}", "--init-box", "900,900,9,9",
                                      "--out", "{out}/m.npz"], "outside"),
    # -- vidtrack reproduce
    "reproduce: unknown experiment": (["reproduce", "nope"], "unknown experiment"),
    "reproduce: nh-1d --steps 1": (["reproduce", "nh-1d", "--steps", "1", "--json", "{out}/r.json"],
                                   "at least 2"),
    "reproduce: svk-linear --window 1": (["reproduce", "svk-linear", "--window", "1", "--json", "{out}/r.json"],
                                         "at least 2"),
    "reproduce: cbt-carlin --channels 2": (["reproduce", "cbt-carlin", "--channels", "2",
                                            "--json", "{out}/r.json"], "--channels >= 4"),
    "reproduce: --runs 0": (["reproduce", "nh-1d", "--runs", "0", "--json", "{out}/r.json"], "at least 1"),
    # -- vidtrack bench
    "bench: --max-frames 1": (["bench", "{video}", "--init-box", "1,1,5,5", "--max-frames", "1"], "at least 2"),
    "bench: missing video": (["bench", "nope.mp4", "--init-box", "1,1,5,5"], "no such"),
    "bench: opencv-mosse on 1x1": (["bench", "{video}", "--init-box", "5,5,1,1", "--filter", "opencv-mosse"],
                                   "at least 8x8"),
    "bench: text file as video": (["bench", "{text}", "--init-box", "1,1,5,5"], "not a video file"),
    "bench: --targets beyond the boxes": (["bench", "{video}", "--init-box", "1,1,5,5", "--targets", "1,2"],
                                          "--targets 2 needs 2 boxes, 1 given"),
    "bench: --targets 0": (["bench", "{video}", "--init-box", "1,1,5,5", "--targets", "0"], "positive counts"),
    "bench: --set of a bad value": (["bench", "{video}", "--init-box", "1,1,5,5", "--filter", "svk",
                                     "--set", "svr.window=2.5"], "expected an integer"),
    # -- vidtrack filters, vidtrack trax (an error before any protocol message)
    "filters: unknown name": (["filters", "nope"], "unknown filter 'nope'"),
    "trax: unknown filter": (["trax", "--filter", "nope"], "unknown filter 'nope'"),
    "trax: --set of an unknown option": (["trax", "--filter", "kalman-cv", "--set", "nope=1"],
                                         "filter kalman-cv: unknown option 'nope'"),
    "trax: missing --config file": (["trax", "--filter", "kalman-cv", "--config", "nope.toml"], "no such file"),
    # -- live inputs ({http} serves the corpus files on 127.0.0.1; {unreachable} is a port nothing listens on)
    "unreachable stream URL": (["{unreachable}", "--init-box", "1,1,5,5"], "Connection refused"),
    "unreachable tcp stream": (["tcp://127.0.0.1:{closed_port}", "--init-box", "1,1,5,5"], "Connection refused"),
    "camera index with no camera": (["57", "--init-box", "1,1,5,5"], "no camera at index 57"),
    "stream that is text": (["{http}/groundtruth_rect.txt", "--init-box", "56,20,31,45"], "not a video"),
    "stream that is audio": (["{http}/audio.wav", "--init-box", "1,1,5,5"], "no video stream"),
    "stream of random bytes": (["{http}/random.mp4", "--init-box", "1,1,5,5"], "cannot open stream"),
    "stream URL that is not found": (["{http}/nope.mjpg", "--init-box", "1,1,5,5"], "404"),
    "--stream-timeout 0": (["{video}", "--init-box", "1,1,5,5", "--stream-timeout", "0"], "positive"),
}

#: vidtrack (track) cases get these outputs too, so a half file would show up in {out}.
#: No --quiet: the progress bar must not add to the one line either.
TRACK_OUTPUTS = ["--boxes", "{out}/b.txt", "--log", "{out}/l.csv"]
SUBCOMMANDS = ("eval", "learn", "reproduce", "bench", "filters", "trax")


def _frames(folder: Path, sizes: list[tuple[int, int]]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for index, (w, h) in enumerate(sizes):
        cv2.imwrite(str(folder / f"{index:04d}.png"), rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    return folder


def _sequence(root: Path, name: str, rows: list[str], frames: int = 3) -> Path:
    _frames(root / name / "img", [(64, 48)] * frames)
    (root / name / "groundtruth_rect.txt").write_text("\n".join(rows) + "\n")
    return root / name


def _no_frames_avi(path: Path) -> Path:
    """An MJPG AVI whose five frames' JPEG data are zeroed: a video stream, no decodable frame."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (64, 48))
    for index in range(5):
        writer.write(np.full((48, 64, 3), 40 * index, np.uint8))
    writer.release()
    data = bytearray(path.read_bytes())
    at, end = data.find(b"movi") + 4, data.find(b"idx1")
    while at < end - 8:  # keep every chunk header, zero its payload
        size = int.from_bytes(data[at + 4:at + 8], "little")
        data[at + 8:at + 8 + size] = bytes(size)
        at += 8 + size + (size & 1)
    path.write_bytes(bytes(data))
    return path


def corpus_files(tmp: Path) -> dict[str, str]:
    """Every input the cases name, made in ``tmp``."""
    files = {"video": str(SAMPLE_VIDEO), "out": str(tmp / "out")}
    (tmp / "out").mkdir()
    (tmp / "empty").mkdir()
    files["empty"] = str(tmp / "empty")
    # Fixed bytes: some random draws happen to parse as a container FFmpeg knows.
    (tmp / "random.mp4").write_bytes(np.random.default_rng(0).bytes(2000))
    files["random"] = str(tmp / "random.mp4")
    (tmp / "zero.mp4").write_bytes(b"")
    files["zero"] = str(tmp / "zero.mp4")
    (tmp / "groundtruth_rect.txt").write_text("56,20,31,45\n" * 100)  # FFmpeg's tty demuxer takes it
    files["text"] = str(tmp / "groundtruth_rect.txt")
    (tmp / "short.txt").write_text("56,20,31,45\n" * 5)
    files["short_text"] = str(tmp / "short.txt")
    (tmp / "notes.mp4").write_text("These are my notes about the video.\n" * 40)
    files["text_mp4"] = str(tmp / "notes.mp4")
    (tmp / "lyrics.mp4").write_text("[00:01.00]first line\n[00:02.50]second line\n")  # FFmpeg's lrc demuxer
    files["lyrics"] = str(tmp / "lyrics.mp4")
    files["no_frames"] = str(_no_frames_avi(tmp / "no_frames.avi"))
    with wave.open(str(tmp / "audio.wav"), "wb") as audio:
        audio.setnchannels(1), audio.setsampwidth(2), audio.setframerate(8000)
        audio.writeframes(np.zeros(8000, np.int16).tobytes())
    files["audio"] = str(tmp / "audio.wav")
    files["mixed"] = str(_frames(tmp / "mixed", [(64, 48), (64, 48), (80, 60), (64, 48)]))
    broken = _frames(tmp / "broken_first", [(64, 48)] * 2)
    (broken / "0000.png").write_bytes(b"not a png")
    files["broken_first"] = str(broken)
    files["dataset"] = str(_sequence(tmp / "data", "Good", ["10,10,20,20"] * 3).parent)
    files["gt_outside"] = str(_sequence(tmp / "bad1", "Outside", ["500,500,20,20"] * 3))
    files["gt_huge"] = str(_sequence(tmp / "bad2", "Huge", ["1,1,1e9,20"] * 3))
    files["gt_three"] = str(_sequence(tmp / "bad3", "Three", ["10,10,20,20", "10,10,20", "10,10,20,20"]))
    files["gt_long"] = str(_sequence(tmp / "bad4", "Long", ["10,10,20,20"] * 4))
    files["gt_zero"] = str(_sequence(tmp / "bad5", "Zero", ["0,0,0,0"] * 3))
    mixed = _sequence(tmp / "bad6", "Mixed", ["10,10,20,20"] * 3)
    _frames(tmp / "bad6" / "Mixed" / "img", [(64, 48), (80, 60)])
    files["gt_mixed"] = str(mixed)
    for name, text in (("boxes_bad", "1,56,20,31,45\n# a comment\n2,10,10,20\n"),
                       ("boxes_duplicate", "\n2,56,20,31,45\n2,10,10,20,20\n"),
                       ("boxes_zero_id", "0,56,20,31,45\n"), ("boxes_zero_width", "1,56,20,0,45\n"),
                       ("boxes_empty", "# nothing\n")):
        (tmp / f"{name}.txt").write_text(text)
        files[name] = str(tmp / f"{name}.txt")
    (tmp / "bad.toml").write_text("[svr\nC = 1\n")
    files["bad_toml"] = str(tmp / "bad.toml")
    (tmp / "unknown.toml").write_text("[fusion]\nredetect = false\n")
    files["unknown_toml"] = str(tmp / "unknown.toml")
    return files


def run_cli(argv: list[str]) -> int:
    """The console script: ``sys.exit(main())`` (argparse errors exit via SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 1


def test_corpus_has_forty_cases():
    assert len(CASES) >= 40
    assert {argv[0] for argv, _ in CASES.values() if argv and argv[0] in SUBCOMMANDS} == set(SUBCOMMANDS)


@pytest.fixture
def served(tmp_path):
    """The files of ``tmp_path`` over HTTP on 127.0.0.1, and a port there that nothing listens on."""
    with FileServer(tmp_path) as server:
        yield {"http": server.url, "closed_port": (port := closed_port()),
               "unreachable": f"http://127.0.0.1:{port}/video.mjpg"}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input(case, tmp_path, capfd, monkeypatch, served):
    monkeypatch.chdir(tmp_path)
    files = {**corpus_files(tmp_path), **served}
    argv, expected = CASES[case]
    if not argv or argv[0] not in SUBCOMMANDS:
        argv = [*TRACK_OUTPUTS, *argv]  # before the case's own options, which win
    argv = [a.format(**files) for a in argv]
    code = run_cli(argv)
    captured = capfd.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2, captured.err
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    assert expected in lines[0], lines[0]
    assert lines[0].startswith("vidtrack"), lines[0]
    assert sorted(os.listdir(files["out"])) == [], "bad input left a file behind"


# -- vidtrack eval on benchmark layouts: each case its own argv, expected text and documented exit code
#: (argv with {placeholders} of :func:`layout_files`, text the one stderr line must contain, exit code).
#: Exit 2: nothing could be evaluated; exit 1: the sequences that can be read are, the others named.
EVAL_LAYOUT_CASES: dict[str, tuple[list[str], str, int]] = {
    "eval: unknown --layout": (["{data}", "--layout", "nope"], "argument --layout: invalid choice: 'nope'", 2),
    "eval: --layout the folder is not": (["{data}", "--layout", "lasot"], "no lasot sequences in", 2),
    "eval: unknown --subset": (["{data}", "--subset", "otb99"], "argument --subset: invalid choice: 'otb99'", 2),
    "eval: --sequences list.txt naming a missing sequence": (["{data}", "--sequences", "{names}"],
                                                             "unknown sequence 'Missing'; sequences in", 2),
    "eval: --sequences list file that names nothing": (["{data}", "--sequences", "{no_names}"], "names no sequence", 2),
    "eval: a dataset's list.txt naming only a missing folder": (["{vot_missing}"], "sequence b: no such folder", 2),
    "eval: a dataset's list.txt naming a missing folder among good ones": (
        ["{vot_partly}"], "1 sequence(s) could not be read: sequence b: no such folder", 1),
    "eval: a folder with no recognisable layout": (["{odd}"], "expected one of the layouts", 2),
}


def layout_files(tmp: Path) -> dict[str, str]:
    """The datasets :data:`EVAL_LAYOUT_CASES` name, made in ``tmp``."""
    files = {"out": str(tmp / "out"), "data": str(_sequence(tmp / "data", "Good", ["10,10,20,20"] * 3).parent)}
    (tmp / "out").mkdir()
    (tmp / "names.txt").write_text("Good\nMissing\n")
    files["names"] = str(tmp / "names.txt")
    (tmp / "no_names.txt").write_text("# only a comment\n\n")
    files["no_names"] = str(tmp / "no_names.txt")
    for name, listed in (("vot_missing", "b\n"), ("vot_partly", "a\nb\n")):
        _frames(tmp / name / "a" / "color", [(64, 48)] * 3)
        (tmp / name / "a" / "groundtruth.txt").write_text("10,10,20,20\n" * 3)
        (tmp / name / "list.txt").write_text(listed)
        files[name] = str(tmp / name)
    _frames(tmp / "odd" / "pictures", [(64, 48)] * 2)   # images, but no ground truth of any layout
    (tmp / "odd" / "notes.txt").write_text("10,10,20,20\n")
    files["odd"] = str(tmp / "odd")
    return files


@pytest.mark.parametrize("case", list(EVAL_LAYOUT_CASES))
def test_eval_bad_layout_input(case, tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    files = layout_files(tmp_path)
    argv, expected, exit_code = EVAL_LAYOUT_CASES[case]
    argv = ["eval", *(a.format(**files) for a in argv), "--filter", "kalman-cv", "--out", f"{files['out']}/e",
            "--in-process", "--no-plots", "-q"]
    code = run_cli(argv)
    captured = capfd.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == exit_code, captured.err
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    assert expected in lines[0], lines[0]
    assert lines[0].startswith("vidtrack"), lines[0]
    if exit_code == 2:
        assert sorted(os.listdir(files["out"])) == [], "bad input left a file behind"
    else:  # the good sequence scored, the missing one its error in summary.json
        import json

        summary = json.loads((Path(files["out"]) / "e" / "summary.json").read_text())["kalman-cv"]
        assert summary["a"]["auc"] > 0 and summary["b"]["error"].startswith("sequence b: no such folder")
