"""Every registered filter on degenerate init boxes: it tracks, or it fails with one line (exit 2).

1x1 boxes, the whole frame, boxes touching a border or a corner, boxes partly
outside, one-pixel slivers.  The cases run in one child process (an OpenCV
tracker that crashes the interpreter fails this test instead of ending the
test session), which prints one result line per case as it goes.
"""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from vidtrack.recipes import registry

#: 96x72 frames: x,y,w,h boxes.
BOXES = {
    "1x1": "40,30,1,1",
    "whole frame": "0,0,96,72",
    "top-left corner": "0,0,20,16",
    "bottom-right corner": "76,56,20,16",
    "partly left of the frame": "-6,20,20,16",
    "sliver 1 px high": "0,30,96,1",
}
FRAMES = 4

CHILD = r"""
import io, json, sys, contextlib
from vidtrack.cli import main
folder, boxes, names = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
for name in names:
    for label, box in boxes.items():
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            try:
                code = main([folder, "--init-box", box, "--filter", name, "--quiet",
                             "--boxes", folder + "/../b.txt"])
            except SystemExit as exc:
                code = exc.code
            except BaseException as exc:  # reported, not raised: the parent test fails on it
                code = f"{type(exc).__name__}: {exc}"
        lines = [l for l in err.getvalue().splitlines() if l.strip()]
        try:
            tracked = sum(1 for _ in open(folder + "/../b.txt")) if code == 0 else 0
        except OSError:
            tracked = 0
        print(json.dumps([name, label, code, lines, tracked]), flush=True)
"""


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    folder = tmp_path_factory.mktemp("degenerate") / "img"
    folder.mkdir()
    rng = np.random.default_rng(0)
    background = rng.integers(40, 200, (72, 96, 3), dtype=np.uint8)
    for index in range(FRAMES):
        image = np.roll(background, 2 * index, axis=1)
        cv2.imwrite(str(folder / f"{index:03d}.png"), image)
    return folder


def test_every_filter_tracks_or_fails_in_one_line(clip):
    names = sorted(registry())
    result = subprocess.run([sys.executable, "-c", CHILD, str(clip), json.dumps(BOXES), json.dumps(names)],
                            capture_output=True, text=True, timeout=500)
    rows = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("[")]
    last = rows[-1][:2] if rows else None
    assert result.returncode == 0, f"child died (exit {result.returncode}) after {last}: {result.stderr[-500:]}"
    assert len(rows) == len(names) * len(BOXES)
    problems = []
    for name, label, code, lines, tracked in rows:
        if code == 0 and tracked == FRAMES:
            continue
        if code == 2 and len(lines) == 1 and lines[0].startswith("vidtrack: error: "):
            continue
        problems.append((name, label, code, lines[-3:], tracked))
    assert not problems, problems
