"""The samples' running second moment, its regularised solve, and the filter learned from every sample."""

import numpy as np
import pytest

from vidtrack.measure.correlation import CorrelationConfig, CorrelationFilter
from vidtrack.measure.dcf import constrained_filter, correlation_response, gaussian_response
from vidtrack.measure.sample_moments import (accumulate_second_moment, factor_regularised, mean_trace,
                                             solve_factored)
from vidtrack.types import Box

SHAPE = (10, 12)


def spectra(rng, count, channels=4):
    """``count`` random sample spectra ``(h, w', d)`` of real ``SHAPE`` windows."""
    return [np.fft.rfft2(rng.normal(size=(*SHAPE, channels)), axes=(0, 1)).astype(np.complex64) for _ in range(count)]


def outer(x):
    return x[..., :, None] * np.conj(x[..., None, :])


def test_the_running_second_moment_and_its_regularised_solve_match_numpy():
    rng = np.random.default_rng(0)
    samples = spectra(rng, 6)
    moment = np.zeros(samples[0].shape + samples[0].shape[-1:], np.complex128)
    accumulate_second_moment(moment, samples[0], 1.0)
    expected = outer(samples[0].astype(np.complex128))
    for x in samples[1:]:
        accumulate_second_moment(moment, x, 0.3)
        expected = 0.7 * expected + 0.3 * outer(x.astype(np.complex128))
    lower = np.tril(np.ones((4, 4), bool))
    assert np.allclose(moment[..., lower], expected[..., lower], rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    assert mean_trace(moment) == pytest.approx(np.mean(np.trace(expected, axis1=2, axis2=3).real), rel=1e-9)
    rhs = spectra(rng, 1)[0]
    ridge = 0.1 * mean_trace(moment)
    solved = solve_factored(factor_regularised(moment, ridge), rhs)
    reference = np.linalg.solve(expected + ridge * np.eye(4), rhs[..., None].astype(np.complex128))[..., 0]
    assert solved.dtype == rhs.dtype and solved.shape == rhs.shape
    assert np.allclose(solved, reference, rtol=1e-4, atol=1e-5 * np.abs(reference).max())


@pytest.mark.parametrize("mu_step", [1.0, 2.0])
def test_the_second_moment_of_one_sample_gives_the_single_sample_filter(mu_step):
    """With one sample, ``S = x x^H``: the per-frequency solve and BACF's Sherman-Morrison closed form agree."""
    x = spectra(np.random.default_rng(1), 1)[0]
    yf = np.fft.rfft2(gaussian_response(SHAPE, 1.5)).astype(np.complex64)
    mask = np.zeros(SHAPE, np.float32)
    mask[2:8, 3:9] = 1
    moment = np.zeros(x.shape + x.shape[-1:], np.complex128)
    accumulate_second_moment(moment, x, 1.0)
    single = constrained_filter(x, yf, mask, SHAPE, iterations=5, mu_step=mu_step)
    every = constrained_filter(x, yf, mask, SHAPE, iterations=5, mu_step=mu_step, moment=moment)
    for a, b in zip(every, single):
        assert np.allclose(a, b, rtol=1e-4, atol=1e-4 * np.abs(b).max())


def test_the_filter_of_every_sample_fits_the_samples_better_than_the_filter_of_their_average():
    """Two appearances that alternate: the average sample's filter fits their mean, which neither is;
    the second moment's filter (ECO's objective) fits each of them."""
    rng = np.random.default_rng(2)
    first, second = spectra(rng, 2)
    y = gaussian_response(SHAPE, 1.5)
    yf = np.fft.rfft2(y).astype(np.complex64)
    mean = (first + second) / 2
    moment = np.zeros(first.shape + first.shape[-1:], np.complex128)
    accumulate_second_moment(moment, first, 1.0)
    accumulate_second_moment(moment, second, 0.5)
    full = np.ones(SHAPE, np.float32)
    errors = {}
    for name, model in (("average", None), ("every", moment)):
        state = None
        for _ in range(40):                               # warm-started, as frame after frame
            g, *state = constrained_filter(mean, yf, full, SHAPE, start=state, moment=model)
        errors[name] = sum(float(np.sum((correlation_response(g, x, SHAPE) - y) ** 2)) for x in (first, second))
    assert errors["every"] < 0.5 * errors["average"]


def moving_target_frames(count):
    rng = np.random.default_rng(3)
    background = np.clip(rng.normal(110, 25, (160, 200, 3)), 0, 255).astype(np.uint8)
    target = np.clip(rng.normal(128, 60, (30, 24, 3)), 0, 255).astype(np.uint8)
    frames = []
    for k in range(count):
        img = background.copy()
        x0, y0 = 70 + 2 * k, 60 + k
        img[y0:y0 + 30, x0:x0 + 24] = target
        frames.append((img, Box(x0, y0, 24, 30)))
    return frames


def test_the_filter_is_solved_every_solve_interval_updates_and_follows_the_target():
    frames = moving_target_frames(10)
    config = CorrelationConfig(second_moment=True, solve_interval=3, scale_filter=False, colour_merge=0.0)
    cf = CorrelationFilter(config)
    cf.initialize(*frames[0])
    solved, previous = [], frames[0][1]
    for img, box in frames[1:]:
        before = cf.filter_fft_
        result = cf.detect(img, previous.center, previous.size)      # the target moved by (2, 1) pixels
        assert np.linalg.norm(result.centre - box.center) < 1.5                # under half a 3.3-pixel cell
        cf.update(img, box)
        solved.append(cf.filter_fft_ is not before)
        previous = box
    assert solved == [False, False, True] * 3
    before = cf.filter_fft_
    cf.update(frames[0][0], frames[0][1], rate=1.0)           # a restart solves at once and forgets the moment
    assert cf.filter_fft_ is not before
    assert np.allclose(np.trace(cf.moment_, axis1=2, axis2=3).real,
                       np.sum(np.abs(cf.model_fft_) ** 2, axis=2), rtol=1e-5)


def test_the_support_is_the_central_fraction_of_the_box():
    img, box = moving_target_frames(1)[0]
    cells = {}
    for support in (1.0, 0.5):
        cf = CorrelationFilter(CorrelationConfig(support=support, scale_filter=False))
        cf.initialize(img, box)
        rows, cols = np.nonzero(cf.mask_)
        cells[support] = (np.ptp(rows) + 1, np.ptp(cols) + 1)
        h = cf.spatial_filter(target_only=False)
        assert np.sum(h[cf.mask_ == 0] ** 2) < 0.02 * np.sum(h ** 2)        # ADMM's filter: (nearly) all inside
    assert cells[0.5][0] < 0.7 * cells[1.0][0] and cells[0.5][1] < 0.7 * cells[1.0][1]
