"""Shared fixtures: synthetic frames, the bundled sample, the shared benchmark sequences."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from vidtrack.types import Box, Frame

REPO = Path(__file__).resolve().parents[1]
SAMPLE_VIDEO = REPO / "data" / "sample.mp4"
SAMPLE_GT = REPO / "data" / "sample_groundtruth.txt"
SEQUENCES = REPO.parent / "shared" / "data" / "sequences"


def load_script(name: str):
    """The module of ``scripts/<name>.py`` (the scripts are not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def read_rows(path: Path) -> np.ndarray:
    """The comma-separated box rows of a ground-truth file the copy scripts write, ``(N, 4)``."""
    return np.array([[float(v) for v in line.split(",")] for line in path.read_text().split()])


def copied_sequence(script, tmp_path: Path, name: str, args: list[str],
                    **sequence) -> tuple[np.ndarray, list[Path]]:
    """Write the synthetic sequence ``name`` (``sequence``: :func:`~vidtrack.eval.synthetic.write_sequence`'s
    options), copy it with a copy script's ``main`` and ``args``, and return the copy's ground-truth rows and
    frame files."""
    from vidtrack.eval.synthetic import write_sequence

    source = tmp_path / "src"
    write_sequence(source / name, **sequence)
    assert script.main([str(source), str(tmp_path / "out"), *args]) == 0
    out = tmp_path / "out" / name
    return read_rows(out / "groundtruth_rect.txt"), sorted((out / "img").iterdir())


def red_extent(image: np.ndarray) -> np.ndarray:
    """0-based ``(x, y, w, h)`` of a synthetic target's pixels (red or yellow: high red channel, low blue)."""
    ys, xs = np.nonzero((image[:, :, 2] > 180) & (image[:, :, 0] < 80))
    return np.array([xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1], float)


def textured_patch(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A colourful checker patch with grain, ``(h, w, 3) uint8``."""
    yy, xx = np.mgrid[0:h, 0:w]
    palette = np.array([[40, 40, 210], [235, 235, 235], [30, 170, 240]], np.uint8)
    patch = palette[((xx // 5) + (yy // 5)) % 3].astype(float) + rng.normal(0, 6, (h, w, 3))
    return np.clip(patch, 0, 255).astype(np.uint8)


def synthetic_sequence(n: int = 30, size=(160, 120), box=(20, 40, 24, 28), velocity=(2.5, 0.8),
                       seed: int = 0) -> tuple[list[Frame], list[Box]]:
    """A textured target moving at constant velocity over a smooth textured background."""
    rng = np.random.default_rng(seed)
    W, H = size
    coarse = rng.random((H // 20 + 2, W // 20 + 2, 3)).astype(np.float32)
    bg = cv2.resize(coarse, (W, H), interpolation=cv2.INTER_CUBIC)
    bg = np.clip(60 + 90 * bg + rng.normal(0, 4, (H, W, 3)), 0, 255).astype(np.uint8)
    x, y, w, h = box
    patch = textured_patch(rng, h, w)
    frames, boxes = [], []
    for k in range(n):
        bx, by = x + velocity[0] * k, y + velocity[1] * k
        img = bg.copy()
        xi, yi = int(round(bx)), int(round(by))
        img[yi:yi + h, xi:xi + w] = patch
        frames.append(Frame(k, img))
        boxes.append(Box(xi, yi, w, h))
    return frames, boxes


@pytest.fixture(scope="session")
def moving_target():
    return synthetic_sequence()


@pytest.fixture(scope="session")
def square_frames(tmp_path_factory) -> Path:
    """A session folder of ``hard_stop_helpers.square_frame`` PNGs, filled on demand by ``write_frames(..., cache=)``."""
    return tmp_path_factory.mktemp("square-frames")


@pytest.fixture(scope="session")
def sample_init_box() -> str:
    return SAMPLE_GT.read_text().splitlines()[0]


def needs_sequences():
    return pytest.mark.skipif(not SEQUENCES.is_dir(), reason="shared benchmark sequences not present")
