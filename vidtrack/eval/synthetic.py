"""Write tiny synthetic benchmark sequences (OTB or MIL layout) for tests and smoke checks."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def write_sequence(folder: str | Path, *, layout: str = "otb", frames: int = 24, size: tuple[int, int] = (96, 72),
                   box: tuple[float, float, float, float] = (16, 20, 16, 18), velocity: tuple[float, float] = (1.5, 0.5),
                   annotate_every: int = 1, first_number: int = 1, frames_range: tuple[int, int] | None = None,
                   separator: str = ",", seed: int = 0) -> np.ndarray:
    """Write a red-and-yellow target moving at constant velocity over a grey textured background.

    Parameters
    ----------
    folder
        The sequence folder to create (its name is the sequence name).
    layout
        ``"otb"``: ``img/0001.png`` + ``groundtruth_rect.txt`` in 1-based pixels;
        ``"mil"``: ``imgs/img00001.png`` + ``<name>_gt.txt`` + ``<name>_frames.txt``
        in 0-based pixels.
    frames, size, box, velocity
        Frame count, ``(W, H)``, the first 0-based box and its motion per frame.
    annotate_every
        Rows not on this stride are written ``0,0,0,0`` (MIL style).
    first_number, frames_range
        Number of the first image file; the MIL ``start,end`` (default: all).
    separator
        Ground-truth separator (``","``, ``"\\t"`` or ``" "``).
    seed
        Background noise seed.

    Returns
    -------
    numpy.ndarray
        ``(frames, 4)`` true boxes in 0-based pixels (not annotated rows included).
    """
    folder = Path(folder)
    rng = np.random.default_rng(seed)
    width, height = size
    background = np.clip(110 + 25 * rng.standard_normal((height, width, 1)), 0, 255).repeat(3, axis=2)
    background = cv2.GaussianBlur(background.astype(np.uint8), (5, 5), 0)
    x0, y0, w, h = box
    target = np.zeros((int(h), int(w), 3), np.uint8)
    target[:] = (30, 30, 220)  # BGR red
    target[: int(h) // 2, : int(w) // 2] = (40, 220, 240)  # yellow quarter
    images = folder / ("img" if layout == "otb" else "imgs")
    images.mkdir(parents=True, exist_ok=True)
    truth = np.zeros((frames, 4))
    rows = []
    origin = 1 if layout == "otb" else 0
    for k in range(frames):
        x, y = round(x0 + velocity[0] * k), round(y0 + velocity[1] * k)
        image = background.copy()
        image[y:y + int(h), x:x + int(w)] = target
        number = first_number + k
        name = f"{number:04d}.png" if layout == "otb" else f"img{number:05d}.png"
        cv2.imwrite(str(images / name), image)
        truth[k] = (x, y, w, h)
        if k % annotate_every == 0:
            rows.append(separator.join(f"{v:g}" for v in (x + origin, y + origin, w, h)))
        else:
            rows.append(separator.join(["0"] * 4))
    text = "\n".join(rows) + "\n"
    if layout == "otb":
        (folder / "groundtruth_rect.txt").write_text(text)
    else:
        (folder / f"{folder.name}_gt.txt").write_text(text)
        start, end = frames_range or (first_number, first_number + frames - 1)
        (folder / f"{folder.name}_frames.txt").write_text(f"{start},{end}\n")
    return truth
