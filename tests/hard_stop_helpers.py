"""Shared helpers of the hard-stop tests: a synthetic moving-square clip and kill -9 at a given frame."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SQUARE = 16


def square_frame(index: int, width: int = 96, height: int = 72) -> np.ndarray:
    """``(height, width, 3) uint8`` BGR: a textured square moving on a circle over a grey gradient."""
    image = np.empty((height, width, 3), np.uint8)
    image[:] = (np.linspace(60, 120, width, dtype=np.uint8))[None, :, None]
    x, y = square_position(index, width, height)
    patch = np.indices((SQUARE, SQUARE)).sum(axis=0) % 4 * 50 + 50
    image[y:y + SQUARE, x:x + SQUARE] = patch[..., None].astype(np.uint8)
    return image


def square_position(index: int, width: int = 96, height: int = 72) -> tuple[int, int]:
    """Top-left corner of the square in frame ``index``."""
    angle = index * 2 * np.pi / 200
    return (int(round((width - SQUARE) / 2 + 20 * np.cos(angle))),
            int(round((height - SQUARE) / 2 + 15 * np.sin(angle))))


def write_frames(folder: Path, count: int, cache: Path | None = None) -> Path:
    """``count`` PNG frames ``00000.png ...`` in ``folder``.

    With ``cache`` (the ``square_frames`` fixture's folder), each frame is encoded there once per session and
    hard-linked into ``folder`` (copied where a link is refused): the same bytes, without encoding thousands
    of PNGs again in every test.  Frames written this way are shared: never modify them in place.
    """
    import shutil

    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    for index in range(count):
        name = f"{index:05d}.png"
        if cache is None:
            cv2.imwrite(str(folder / name), square_frame(index))
            continue
        cached = cache / name
        if not cached.exists():                      # encoded whole under another name, then renamed
            cv2.imwrite(str(cache / f"{index:05d}.part.png"), square_frame(index))
            os.replace(cache / f"{index:05d}.part.png", cached)
        try:
            os.link(cached, folder / name)
        except OSError:
            shutil.copyfile(cached, folder / name)
    return folder


def line_count(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


def run_and_kill(args: list[str], watch: Path, at_lines: int, *, cwd: Path, timeout: float = 120.0) -> None:
    """Start ``python -m vidtrack ARGS`` in its own session and SIGKILL the whole group once
    ``watch`` holds ``at_lines`` lines (or, with ``at_lines=0``, once ``watch`` exists)."""
    process = subprocess.Popen([sys.executable, "-m", "vidtrack", *args], cwd=cwd, stdin=subprocess.DEVNULL,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                raise AssertionError(f"vidtrack ended (exit {process.returncode}) before it was killed")
            if (watch.exists() and at_lines == 0) or (at_lines and line_count(watch) >= at_lines):
                break
            time.sleep(0.005)
        else:
            raise AssertionError(f"{watch} did not reach {at_lines} lines in {timeout} s")
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()


def mounted_tmpfs(folder: Path, size: str, *, read_only: bool = False, exist_ok: bool = False):
    """Yield ``folder`` as a fresh tmpfs of ``size`` (``"64k"``), unmounted afterwards: a disk that fills up.

    ``read_only`` mounts it read-only (a folder nothing can be written into);
    ``exist_ok`` mounts over an existing empty ``folder``.

    Skips the test with a reason unless running as root with mount(8).
    """
    import shutil

    import pytest

    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs needs root and mount(8)")
    folder.mkdir(exist_ok=exist_ok)
    options = f"size={size}" + (",ro" if read_only else "")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                             capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)
