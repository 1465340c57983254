"""Metrics: hand-computed values, skipping of unannotated rows, inputs never modified."""

from __future__ import annotations

import numpy as np
import pytest

from vidtrack.eval import metrics as M


def test_iou_hand_values():
    a = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [5, 0, 10, 10], [20, 20, 5, 5], [2.5, 2.5, 5, 5]], float)
    np.testing.assert_allclose(M.iou(a, b), [1.0, 50 / 150, 0.0, 25 / 100])


def test_iou_invalid_rows_give_zero():
    a = np.array([[0, 0, 10, 10], [0, 0, 10, 10]], float)
    b = np.array([[0, 0, 0, 0], [np.nan, 0, 10, 10]], float)
    np.testing.assert_array_equal(M.iou(a, b), [0.0, 0.0])


def test_center_error_and_shift_invariance():
    a = np.array([[0, 0, 10, 10], [10, 10, 4, 4]], float)
    b = np.array([[3, 4, 10, 10], [10, 10, 8, 8]], float)
    np.testing.assert_allclose(M.center_error(a, b), [5.0, np.hypot(2, 2)])
    np.testing.assert_allclose(M.iou(a + [1, 1, 0, 0], b + [1, 1, 0, 0]), M.iou(a, b))


def test_success_auc_precision_pascal_by_hand():
    ious = np.array([1.0, 0.5, 0.0, 0.26])
    # thresholds 0,0.05,...,1: IoU 1.0 beats 20 of 21, 0.5 beats 10 (0..0.45), 0.26 beats 6 (0..0.25), 0 none
    assert M.success_auc(ious) == pytest.approx((20 + 10 + 0 + 6) / (21 * 4))
    assert M.pascal_score(ious) == pytest.approx(0.25)  # strictly > 0.5
    errors = np.array([0.0, 20.0, 20.5, np.inf])
    assert M.precision_at(errors, 20) == pytest.approx(0.5)  # <= 20


def test_score_skips_unannotated_rows_and_respects_mask():
    gt = np.array([[0, 0, 10, 10], [0, 0, 0, 0], [0, 0, 10, 10], [5, 5, -1, 3]], float)
    res = np.array([[0, 0, 10, 10], [50, 50, 10, 10], [100, 100, 10, 10], [0, 0, 10, 10]], float)
    s = M.score(res, gt)
    assert s["frames"] == 2
    assert s["pascal"] == pytest.approx(0.5)
    masked = M.score(res, gt, mask=[True, True, False, True])
    assert masked["frames"] == 1 and masked["auc"] == pytest.approx(20 / 21)
    assert M.score(res, gt, mask=[False] * 4)["frames"] == 0


def test_metrics_never_modify_inputs():
    rng = np.random.default_rng(1)
    gt = rng.uniform(1, 50, (20, 4))
    gt[3] = 0
    res = rng.uniform(1, 50, (20, 4))
    res[5, 0] = np.nan
    mask = rng.random(20) > 0.3
    copies = gt.copy(), res.copy(), mask.copy()
    M.score(res, gt, mask)
    M.frame_scores(res, gt, mask)
    M.success_curve(M.iou(res, gt))
    M.precision_curve(M.center_error(res, gt))
    for original, copy in zip((gt, res, mask), copies):
        np.testing.assert_array_equal(original, copy)


def test_shape_mismatch_raises():
    with pytest.raises(ValueError):
        M.score(np.zeros((3, 4)), np.zeros((4, 4)))
