"""One colour per target ID, shared by the annotated video and the Rerun recording."""

from __future__ import annotations

#: Well-separated BGR colours (a qualitative palette); IDs beyond it cycle.
TARGET_COLOURS_BGR: tuple[tuple[int, int, int], ...] = (
    (0, 200, 0),      # green
    (255, 128, 0),    # azure
    (0, 140, 255),    # orange
    (200, 0, 200),    # magenta
    (0, 220, 220),    # yellow
    (255, 255, 0),    # cyan
    (60, 60, 230),    # red
    (180, 120, 255),  # pink
    (255, 80, 160),   # violet
    (120, 200, 120),  # sage
)


def target_colour(target_id: int) -> tuple[int, int, int]:
    """The BGR colour of target ``target_id`` (IDs start at 1; the same ID, the same colour everywhere)."""
    return TARGET_COLOURS_BGR[(int(target_id) - 1) % len(TARGET_COLOURS_BGR)]


def target_colour_rgb(target_id: int) -> tuple[int, int, int]:
    """The same colour as :func:`target_colour`, as RGB (for the Rerun recording)."""
    b, g, r = target_colour(target_id)
    return r, g, b
