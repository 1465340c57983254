"""Frame sources read 16-bit, grey and EXIF-rotated images, and the H.264 annotated video plays."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import cv2

from vidtrack.errors import SourceError
from vidtrack.sinks.h264 import FRAGMENTED_MOVFLAGS, H264Writer, count_frames, even_frame
from vidtrack.sources import ImageFolderSource, image_size, read_image


def test_16_bit_png_keeps_its_high_byte(tmp_path):
    image = np.full((12, 16), 0x1234, np.uint16)
    image[:, 8:] = 0xFF00
    cv2.imwrite(str(tmp_path / "a.png"), image)
    out = read_image(tmp_path / "a.png")
    assert out.dtype == np.uint8 and out.shape == (12, 16, 3)
    assert np.all(out[:, :8] == 0x12) and np.all(out[:, 8:] == 0xFF)


def test_16_bit_frames_are_not_rescaled_frame_by_frame(tmp_path):
    for index, value in enumerate((1000, 30000)):   # a dark frame stays dark
        cv2.imwrite(str(tmp_path / f"{index}.png"), np.full((8, 8, 3), value, np.uint16))
    frames = list(ImageFolderSource(tmp_path))
    assert frames[0].image.max() == 1000 >> 8 and frames[1].image.max() == 30000 >> 8


def test_grey_png_becomes_three_equal_channels(tmp_path):
    grey = np.arange(48, dtype=np.uint8).reshape(6, 8)
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    out = read_image(tmp_path / "g.png")
    assert out.shape == (6, 8, 3) and all(np.array_equal(out[..., c], grey) for c in range(3))


def _exif_jpeg(path, orientation):
    image = np.zeros((48, 64, 3), np.uint8)
    image[:8, :8] = 255                                 # a white corner, top-left as stored
    exif = Image.Exif()
    exif[0x0112] = orientation
    Image.fromarray(image).save(path, quality=95, exif=exif)


def test_exif_rotated_jpeg_is_upright(tmp_path):
    _exif_jpeg(tmp_path / "r.jpg", 6)                   # 6: the viewer rotates 90 degrees clockwise
    assert image_size(tmp_path / "r.jpg") == (48, 64)
    out = read_image(tmp_path / "r.jpg")
    assert out.shape == (64, 48, 3)
    assert out[:8, -8:].mean() > 200 and out[:8, :8].mean() < 50   # the corner moved to the top right


def test_folder_of_rotated_and_upright_photos_of_one_size(tmp_path):
    _exif_jpeg(tmp_path / "0.jpg", 6)
    Image.fromarray(np.zeros((64, 48, 3), np.uint8)).save(tmp_path / "1.jpg")
    source = ImageFolderSource(tmp_path)
    assert source.size == (48, 64)
    assert [f.image.shape for f in source] == [(64, 48, 3)] * 2


def test_mixed_sizes_name_the_first_odd_file(tmp_path):
    for name, (w, h) in {"a.png": (16, 12), "b.png": (16, 12), "c.png": (20, 12), "d.png": (8, 8)}.items():
        cv2.imwrite(str(tmp_path / name), np.zeros((h, w, 3), np.uint8))
    with pytest.raises(SourceError, match=r"c\.png is 20x12 but a\.png is 16x12"):
        ImageFolderSource(tmp_path)


def test_even_frame_pads_odd_sides_with_the_edge():
    image = np.arange(3 * 5 * 3, dtype=np.uint8).reshape(3, 5, 3)
    out = even_frame(image)
    assert out.shape == (4, 6, 3)
    assert np.array_equal(out[:3, :5], image) and np.array_equal(out[3, :5], image[2])


def test_h264_video_is_fragmented_and_plays(tmp_path):
    import av

    path = tmp_path / "v.mp4"
    writer = H264Writer(path, fps=25.0, batch=10)
    rng = np.random.default_rng(0)
    for _ in range(37):
        writer.write(rng.integers(0, 255, (33, 47, 3), dtype=np.uint8))   # odd sides
    writer.close()
    writer.close()                                                        # twice is fine
    data = path.read_bytes()
    assert data.find(b"moov") < data.find(b"moof") < data.find(b"mdat")   # index first, then fragments
    assert data.count(b"moof") >= 3                                       # one per 10 frames
    assert count_frames(path) == 37
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264" and stream.codec_context.pix_fmt == "yuv420p"
        assert (stream.width, stream.height) == (48, 34) and stream.average_rate == 25
    assert "empty_moov" in FRAGMENTED_MOVFLAGS
