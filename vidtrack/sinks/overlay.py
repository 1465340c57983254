"""The annotated video's overlay: every target's boxes and label, and the frame index, legible at any frame size.

Text is drawn from one rendering of its glyphs: the fill is OpenCV's Hershey
font rendered once into an alpha mask, and the outline is that same mask
dilated by a disc (a grey-level dilation, so the anti-aliased edges stay
smooth).  The outline therefore surrounds every glyph exactly where the fill
is, whatever the font's thickness-dependent advance; drawing the string twice
with two thicknesses would place the glyphs of the two passes apart.  Sizes
(text height, line widths, outline radius) are fractions of the frame, so a
1920x1080 video reads like a 320x240 one.

Each target has its colour (:func:`~vidtrack.sinks.palette.target_colour`)
and a tag above its box on a filled background in that colour, with black
or white text, whichever contrasts more (WCAG 2 contrast ratio).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import cv2
import numpy as np

from ..types import Box, TrackState
from .palette import target_colour

FONT = cv2.FONT_HERSHEY_SIMPLEX
#: Height in pixels of a capital letter of :data:`FONT` at scale 1.
FONT_CAP_HEIGHT = 22
REGION_COLOUR = (160, 160, 160)     # grey: the search region
WHITE = (255, 255, 255)
BLACK = (0, 0, 0)


@dataclass(frozen=True)
class TextStyle:
    """Sizes of the overlay's text and lines for one frame size, in pixels."""

    height: int
    """Height of a capital letter."""
    thickness: int
    """Stroke width of the glyphs."""
    outline: int
    """Radius of the outline around the glyphs."""
    line: int
    """Width of a target's estimated box."""

    @property
    def scale(self) -> float:
        """OpenCV's font scale giving :attr:`height`."""
        return self.height / FONT_CAP_HEIGHT

    @property
    def pad(self) -> int:
        """Margin around the glyphs: room for the outline, or a tag's padding."""
        return self.outline + self.thickness


def text_style(width: int, height: int) -> TextStyle:
    """The overlay's sizes for a ``width`` x ``height`` frame.

    Capitals are 1/28 of the frame's height (of 3/4 of its width for a
    very wide frame), never under 9 pixels: 9 px at 320x240, 17 px at
    640x480, 39 px at 1920x1080.
    """
    side = min(height, 0.75 * width)
    text_h = max(9, int(round(side / 28.0)))
    return TextStyle(height=text_h, thickness=max(1, int(round(text_h / 11.0))),
                     outline=max(1, int(round(text_h / 7.0))), line=max(1, int(round(side / 240.0))))


def text_alpha(text: str, style: TextStyle) -> tuple[np.ndarray, np.ndarray, int]:
    """The glyphs of ``text`` and their outline as alpha masks.

    Returns
    -------
    fill, outline : ndarray
        ``(h, w)`` float32 in [0, 1]; ``outline`` is ``fill`` dilated by a
        disc of radius ``style.outline`` (so ``outline >= fill`` everywhere).
    baseline : int
        Row of the text's baseline in the masks (descenders go below it).
    """
    (w, h), descent = cv2.getTextSize(text, FONT, style.scale, style.thickness)
    pad = style.pad
    canvas = np.zeros((h + descent + 2 * pad, w + 2 * pad), np.uint8)
    baseline = pad + h
    cv2.putText(canvas, text, (pad, baseline), FONT, style.scale, 255, style.thickness, cv2.LINE_AA)
    fill = canvas.astype(np.float32) / 255.0
    size = 2 * style.outline + 1
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    return fill, cv2.dilate(fill, disc), baseline


def _blend(image: np.ndarray, alpha: np.ndarray, colour, x: int, y: int) -> None:
    """Paint ``colour`` onto ``image`` with ``alpha`` placed at ``(x, y)``, clipped to the image, in place."""
    H, W = image.shape[:2]
    h, w = alpha.shape
    x0, y0, x1, y1 = max(0, x), max(0, y), min(W, x + w), min(H, y + h)
    if x0 >= x1 or y0 >= y1:
        return
    a = np.ascontiguousarray(alpha[y0 - y:y1 - y, x0 - x:x1 - x])
    roi = image[y0:y1, x0:x1]
    paint = np.empty_like(roi)
    paint[:] = colour
    image[y0:y1, x0:x1] = cv2.blendLinear(paint, roi, a, 1.0 - a)    # colour * a + image * (1 - a)


def draw_text(image: np.ndarray, text: str, x: int, y: int, style: TextStyle, *,
              colour=WHITE, outline=BLACK) -> tuple[int, int, int, int]:
    """Draw ``text`` with its top-left corner (margin included) at ``(x, y)``, in place.

    Parameters
    ----------
    image
        ``(H, W, 3) uint8`` BGR, changed in place.
    colour, outline
        BGR of the glyphs and of the outline around them (``None``: no outline).

    Returns
    -------
    tuple
        ``(x0, y0, x1, y1)`` of the drawn area, margin included (may extend past the image).
    """
    fill, ring, _ = text_alpha(text, style)
    if outline is not None:
        _blend(image, ring, outline, x, y)
    _blend(image, fill, colour, x, y)
    return x, y, x + fill.shape[1], y + fill.shape[0]


def relative_luminance(colour) -> float:
    """WCAG 2 relative luminance of a BGR colour (sRGB, 0..255)."""
    b, g, r = (float(c) / 255.0 for c in colour)

    def linear(c: float) -> float:
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
    return 0.2126 * linear(r) + 0.7152 * linear(g) + 0.0722 * linear(b)


def contrast_ratio(a, b) -> float:
    """WCAG 2 contrast ratio of two BGR colours, 1 (none) to 21 (black on white)."""
    la, lb = sorted((relative_luminance(a), relative_luminance(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)


def text_colour_on(background) -> tuple[int, int, int]:
    """Black or white, whichever contrasts more with ``background`` (BGR)."""
    return BLACK if contrast_ratio(BLACK, background) >= contrast_ratio(WHITE, background) else WHITE


def tag_text(target_id: int, state: TrackState) -> str:
    """A target's label: ``#ID confidence status``."""
    return f"#{target_id} {state.confidence:.2f} {state.status}"


def draw_tag(image: np.ndarray, text: str, box: Box, colour, style: TextStyle, *,
             below: int = 0) -> tuple[int, int, int, int]:
    """Draw ``text`` on a filled ``colour`` background just above ``box`` (inside the frame), in place.

    The tag sits on the box's top edge, left-aligned with it; when there is
    no room above, it goes just below the top edge, and it is shifted
    sideways to stay inside the frame.  ``below``: the tag starts no higher
    than this row when it would otherwise overlap the rows above it.

    Returns
    -------
    tuple
        ``(x0, y0, x1, y1)`` of the tag's background.
    """
    H, W = image.shape[:2]
    fill, _, _ = text_alpha(text, style)
    h, w = fill.shape
    x = int(round(box.x)) - style.line // 2
    y = int(round(box.y)) - style.line // 2 - h
    if y < 0:
        y = int(round(box.y)) + (style.line + 1) // 2
    x = min(max(0, x), max(0, W - w))
    y = min(max(below, y), max(0, H - h))
    image[max(0, y):min(H, y + h), max(0, x):min(W, x + w)] = colour
    _blend(image, fill, text_colour_on(colour), x, y)
    return x, y, x + w, y + h


def _corners(box: Box) -> tuple[tuple[int, int], tuple[int, int]]:
    x, y, w, h = box.as_array()
    return (int(round(x)), int(round(y))), (int(round(x + w)), int(round(y + h)))


def draw_box(image: np.ndarray, box: Box | None, colour, thickness: int, *, dashed: bool = False) -> None:
    """A rectangle for ``box`` (nothing for ``None`` or an empty box), solid or dashed, in place.

    Drawn without anti-aliasing: the edges are axis-aligned on whole pixels,
    so they keep the exact colour.
    """
    if box is None or not box.is_valid():
        return
    (x0, y0), (x1, y1) = _corners(box)
    if not dashed:
        cv2.rectangle(image, (x0, y0), (x1, y1), colour, thickness, cv2.LINE_8)
        return
    dash = max(4, 4 * thickness)
    for (ax, ay), (bx, by) in (((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))):
        length = max(abs(bx - ax), abs(by - ay))
        for start in range(0, max(1, length), 2 * dash):
            end = min(length, start + dash)
            t0, t1 = start / max(1, length), end / max(1, length)
            p = (int(round(ax + (bx - ax) * t0)), int(round(ay + (by - ay) * t0)))
            q = (int(round(ax + (bx - ax) * t1)), int(round(ay + (by - ay) * t1)))
            cv2.line(image, p, q, colour, thickness, cv2.LINE_8)


def lighter(colour, amount: float = 0.45) -> tuple[int, int, int]:
    """``colour`` mixed with white by ``amount`` (0: unchanged, 1: white)."""
    return tuple(int(round(c + (255 - c) * amount)) for c in colour)


def draw_overlay(image: np.ndarray, targets: Mapping[int, TrackState], *, frame_index: int,
                 filter_name: str | None = None) -> np.ndarray:
    """A copy of ``image`` with every target and the frame index drawn on it.

    Parameters
    ----------
    image
        ``(H, W, 3) uint8`` BGR.
    targets
        Target ID -> that target's state on this frame.
    frame_index
        Shown top-left (0-based, as the boxes and logs count frames), with ``filter_name``.

    Returns
    -------
    ndarray
        ``(H, W, 3) uint8`` BGR. Per target, in its colour: the estimate
        (thick; dashed while the target is lost), the measurement (thin,
        lighter), the prediction (thin, lighter, dashed) and a tag
        ``#ID confidence status``; the search region is thin grey.
    """
    out = image.copy()
    style = text_style(out.shape[1], out.shape[0])
    thin = max(1, style.line // 2)
    ordered = sorted(targets.items())
    for _, state in ordered:
        draw_box(out, state.search_region, REGION_COLOUR, thin)
    for target_id, state in ordered:
        colour = lighter(target_colour(target_id))
        draw_box(out, state.predicted, colour, thin, dashed=True)
        draw_box(out, state.measured, colour, thin)
    for target_id, state in ordered:
        draw_box(out, state.box, target_colour(target_id), style.line, dashed=state.status == "lost")
    header = f"frame {frame_index}" + (f"  {filter_name}" if filter_name else "")
    header_w, header_h = text_alpha(header, style)[0].shape[::-1]
    for target_id, state in ordered:
        if state.box.is_valid():
            # a tag under the header (top-left) moves down below it
            below = header_h if state.box.x < header_w else 0
            draw_tag(out, tag_text(target_id, state), state.box, target_colour(target_id), style, below=below)
    draw_text(out, header, 0, 0, style)
    return out
