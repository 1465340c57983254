"""The annotated video's overlay: outline and fill of the text line up, labels stay legible, one colour per ID.

The text is checked on the rendered image, at several frame sizes: drawn
on a saturated green background with white glyphs and a black outline, any
blend of glyph and outline is a neutral grey while any pixel that shows the
background is green; so "the outline surrounds the glyphs" is "no green
pixel near a glyph pixel", and "fill and outline share the glyph positions"
is "the glyph pixels are those of the string drawn once, alone".
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vidtrack.sinks.overlay import (BLACK, FONT, WHITE, _blend, contrast_ratio, draw_overlay, draw_tag, draw_text,
                                    tag_text, text_alpha, text_colour_on, text_style)
from vidtrack.sinks.palette import TARGET_COLOURS_BGR, target_colour
from vidtrack.sinks.video import AnnotatedVideoSink
from vidtrack.types import Box, Frame, TrackState

SIZES = [(320, 240), (640, 480), (1920, 1080), (1280, 360)]
TEXTS = ["#250 mil conf 1.00 tracking", "frame 12345  opencv-csrt", "#7 0.03 lost"]
GREEN = (0, 255, 0)


def _greenness(image: np.ndarray) -> np.ndarray:
    """How much a pixel leans to green: 0 for any grey (a glyph/outline blend), 255 for the background."""
    b, g, r = (image[..., k].astype(int) for k in range(3))
    return g - (b + r) // 2


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _glyph_pixels(image: np.ndarray) -> np.ndarray:
    return (image.min(axis=2) > 200) & (_greenness(image) < 20)        # white: the fill


def _background_next_to_glyph(image: np.ndarray, style) -> bool:
    """Whether green shows within (outline radius - 1) of a glyph pixel: an outline that fails to surround."""
    near_glyph = cv2.dilate(_glyph_pixels(image).astype(np.uint8), _disc(max(1, style.outline - 1))).astype(bool)
    return bool((near_glyph & (_greenness(image) > 100)).any())


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("text", TEXTS)
def test_outline_surrounds_every_glyph_pixel(size, text):
    width, height = size
    style = text_style(width, height)
    image = np.zeros((height, width, 3), np.uint8)
    image[:] = GREEN
    x0, y0, x1, y1 = draw_text(image, text, 3, 5, style)
    assert x1 <= width and y1 <= height, "the sample string fits the frame"
    glyph = _glyph_pixels(image)
    assert glyph.sum() > 5 * len(text.replace(" ", ""))
    # every pixel within (radius - 1) of a glyph pixel is glyph or outline, never background
    assert not _background_next_to_glyph(image, style)
    # the outline really is there: a dark ring around the glyphs
    dark = image.max(axis=2) < 60
    assert dark.sum() > glyph.sum() * 0.2


@pytest.mark.parametrize("size", SIZES)
def test_the_check_catches_a_fill_two_pixels_off_its_outline(size):
    width, height = size
    style = text_style(width, height)
    fill, ring, _ = text_alpha(TEXTS[0], style)
    for shift, caught in ((0, False), (2, True)):
        image = np.zeros((height, width, 3), np.uint8)
        image[:] = GREEN
        _blend(image, ring, BLACK, 3, 5)
        _blend(image, fill, WHITE, 3 + shift, 5)
        assert _background_next_to_glyph(image, style) is caught


@pytest.mark.parametrize("size", SIZES)
def test_fill_is_the_string_drawn_once(size):
    """Glyph positions: the white pixels are exactly where cv2.putText puts the string alone."""
    width, height = size
    style = text_style(width, height)
    text = TEXTS[0]
    image = np.zeros((height, width, 3), np.uint8)
    image[:] = GREEN
    draw_text(image, text, 0, 0, style)
    reference = np.zeros((height, width), np.uint8)
    _, baseline = cv2.getTextSize(text, FONT, style.scale, style.thickness)
    text_h = cv2.getTextSize(text, FONT, style.scale, style.thickness)[0][1]
    cv2.putText(reference, text, (style.pad, style.pad + text_h), FONT, style.scale, 255, style.thickness, cv2.LINE_AA)
    glyph = _glyph_pixels(image)
    core = reference > 200
    # every pixel the lone string fills solidly is white in the overlay, and nothing white lies outside it
    assert (glyph[core]).all()
    assert not (glyph & (reference == 0)).any()
    # the glyphs' horizontal extent is the lone string's (no drift to either side)
    cols = np.flatnonzero(glyph.any(axis=0))
    ref_cols = np.flatnonzero(core.any(axis=0))
    assert abs(cols[0] - ref_cols[0]) <= 1 and abs(cols[-1] - ref_cols[-1]) <= 1


def test_sizes_scale_with_the_frame():
    small, medium, large = (text_style(w, h) for w, h in ((320, 240), (640, 480), (1920, 1080)))
    assert 9 <= small.height < medium.height < large.height
    assert large.height / medium.height == pytest.approx(1080 / 480, rel=0.1)
    assert small.line <= medium.line < large.line
    for style, (w, _h) in zip((small, medium, large), ((320, 240), (640, 480), (1920, 1080))):
        fill, ring, _ = text_alpha("#250 mil conf 1.00 tracking", style)
        assert fill.shape[1] < w                        # the full label fits across the frame
        assert (ring >= fill).all()                     # the outline covers every glyph pixel
        # the glyphs' height (a capital) in the rendered mask is the style's height, within the anti-aliasing
        rows = np.flatnonzero((text_alpha("H", style)[0] > 0.5).any(axis=1))
        assert abs((rows[-1] - rows[0] + 1) - style.height) <= style.thickness + 1


def test_tag_text_contrasts_with_every_palette_colour():
    for colour in TARGET_COLOURS_BGR:
        assert contrast_ratio(text_colour_on(colour), colour) >= 4.5   # WCAG AA for normal text


def _state(box, status="tracking", confidence=0.8, **kw):
    return TrackState(7, box, confidence, status, **kw)


@pytest.mark.parametrize("size", [(320, 240), (1920, 1080)])
def test_each_target_in_its_colour_with_its_tag(size):
    width, height = size
    f = width / 320
    image = np.full((height, width, 3), 90, np.uint8)
    targets = {1: _state(Box(40 * f, 80 * f, 40 * f, 60 * f)),
               2: _state(Box(150 * f, 100 * f, 50 * f, 50 * f), "lost", 0.1),
               3: _state(Box(240 * f, 30 * f, 40 * f, 70 * f))}
    out = draw_overlay(image, targets, frame_index=7, filter_name="mil")
    style = text_style(width, height)
    for target_id, state in targets.items():
        colour = np.array(target_colour(target_id))
        (x0, y0), (x1, y1) = (int(state.box.x), int(state.box.y)), (int(state.box.x + state.box.w),
                                                                   int(state.box.y + state.box.h))
        # the bottom edge of the box (no tag there) is drawn in the target's colour
        edge = out[y1, x0 + 2:x1 - 2]
        exact = np.all(edge == colour, axis=1)
        assert exact.mean() > (0.4 if state.status == "lost" else 0.9), target_id   # dashed while lost
        # its tag: a patch of its colour right above the box, with the label's text in it
        tag_band = out[max(0, y0 - style.height - 2 * style.pad):y0, x0:x1]
        assert np.all(tag_band == colour, axis=2).mean() > 0.3, target_id
    assert tag_text(2, targets[2]) == "#2 0.10 lost"


def test_tag_stays_inside_the_frame_and_holds_its_text():
    image = np.zeros((240, 320, 3), np.uint8)
    style = text_style(320, 240)
    colour = target_colour(3)
    x0, y0, x1, y1 = draw_tag(image, "#3 0.95 tracking", Box(300, 0, 20, 30), colour, style)
    assert 0 <= x0 and x1 <= 320 and 0 <= y0 and y1 <= 240           # pushed left and below the top edge
    inside = image[y0:y1, x0:x1]
    text = np.any(inside != colour, axis=2)
    assert text.any() and (image.sum(axis=2)[:, :x0] == 0).all()     # nothing drawn outside the tag
    # every other pixel is a blend of the tag's colour and the text's: nothing else is drawn in the tag
    ink = np.array(text_colour_on(colour), float)
    bg = np.array(colour, float)
    share = ((inside[text] - bg) @ (ink - bg)) / ((ink - bg) @ (ink - bg))     # 0: background, 1: ink
    blend = bg + share[:, None] * (ink - bg)
    assert np.abs(inside[text] - blend).max() <= 2
    assert (share > 0.6).sum() > 20                                            # and the text is there


def test_sink_accepts_a_state_or_a_mapping(tmp_path):
    """A single TrackState is target 1; a mapping draws each target; the video has every frame."""
    from vidtrack.sinks.h264 import count_frames

    frames = [Frame(k, np.full((120, 160, 3), 60, np.uint8)) for k in range(6)]
    single, many = tmp_path / "single.avi", tmp_path / "many.mp4"
    sink = AnnotatedVideoSink(single, filter_name="kalman-cv", fps=10)
    for frame in frames:
        sink.write(frame, _state(Box(20, 30, 30, 40)))
    sink.close()
    sink = AnnotatedVideoSink(many, filter_name="kalman-cv", fps=10)
    for frame in frames:
        sink.write(frame, {1: _state(Box(20, 30, 30, 40)), 4: _state(Box(90, 40, 30, 40), "lost")})
    sink.close()
    capture = cv2.VideoCapture(str(single))
    ok, image = capture.read()
    capture.release()
    assert ok and image.shape == (120, 160, 3)
    assert count_frames(many) == 6
    single_drawn = draw_overlay(frames[0].image, {1: _state(Box(20, 30, 30, 40))}, frame_index=0,
                                filter_name="kalman-cv")
    mapping_drawn = draw_overlay(frames[0].image, {1: _state(Box(20, 30, 30, 40))}, frame_index=0,
                                 filter_name="kalman-cv")
    assert np.array_equal(single_drawn, mapping_drawn)
    assert np.abs(image.astype(int) - single_drawn.astype(int)).mean() < 6   # MJPG's loss only
