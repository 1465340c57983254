"""Staple's colour-histogram model: per-pixel object probability and the box score it gives."""

import numpy as np

from vidtrack.measure.colour_model import ColourHistogramModel, box_masks, colour_bins


def test_colour_bins_are_joint_and_grey_lies_on_the_diagonal():
    patch = np.array([[[0, 0, 0], [255, 255, 255], [8, 0, 0]]], np.uint8)
    assert colour_bins(patch, 32).tolist() == [[0, 32 ** 3 - 1, 32 * 32]]
    grey = np.array([[0, 255]], np.uint8)
    assert colour_bins(grey, 32).tolist() == [[0, 32 ** 3 - 1]]


def test_masks_keep_the_box_border_out_of_both_regions():
    obj, bg = box_masks((100, 100), (20, 40), inner=0.1, context=1.0)
    assert obj.sum() == 16 * 32 and not np.any(obj & bg)
    assert bg[50, 50 - 25] and not bg[50, 50 - 9] and not bg[50, 50 - 31]


def test_object_probability_separates_colours_and_the_box_score_peaks_on_the_target():
    rng = np.random.default_rng(0)
    patch = np.zeros((120, 160, 3), np.uint8)
    patch[:] = (40, 160, 60)                                              # green background
    patch += rng.integers(0, 20, patch.shape, dtype=np.uint8)
    patch[45:75, 65:95] = (200, 40, 40) + rng.integers(0, 20, (30, 30, 3), dtype=np.uint8)   # a blue target at the centre
    model = ColourHistogramModel()
    model.update(patch, (30, 30))
    beta = model.likelihood(patch)
    assert beta[50:70, 70:90].mean() > 0.9 and beta[:30].mean() < 0.1
    moved = np.roll(patch, (8, -12), axis=(0, 1))                           # the target 12 px left, 8 px down
    score = model.response(moved, (30, 30), (15, 21), 4)
    r, c = np.unravel_index(int(np.argmax(score)), score.shape)
    assert (r - 15 // 2, c - 21 // 2) == (2, -3)


def test_box_masks_with_an_offset_are_the_centred_masks_moved():
    obj, bg = box_masks((100, 120), (20, 30))
    obj_moved, bg_moved = box_masks((100, 120), (20, 30), offset=(7, -4))
    assert np.array_equal(obj_moved, np.roll(obj, (-4, 7), axis=(0, 1)))
    assert np.array_equal(bg_moved, np.roll(bg, (-4, 7), axis=(0, 1)))
