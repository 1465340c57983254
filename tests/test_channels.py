"""cos² channel encoding/decoding and channel Bayesian tracking steps (vidtrack.channels, vidtrack.filters.channels)."""

from __future__ import annotations

import numpy as np
import pytest

from vidtrack.channels import (
    ChannelBasis, cbt_update, channel_product, cos2_kernel, decode, decode_modes, decode_nd, decode_nd_modes,
    diagonal_history, embedded_matrix, embedded_predict, encode, encode_density, encode_nd, encode_samples,
    normalized, position_conditional, random_walk_displacement, shift_matrix,
)
from vidtrack.filters.channels import mean_field_update, product_likelihood


def test_kernel_is_a_partition_of_unity_with_three_active_channels():
    t = np.linspace(-3, 3, 601)
    total = sum(cos2_kernel(t - j) for j in range(-6, 7))
    assert np.allclose(total, 1.0)
    assert cos2_kernel(1.5) == 0.0 and cos2_kernel(1.49) > 0
    w = encode(3.3, ChannelBasis(0.0, 10.0, 13))
    assert np.count_nonzero(w) == 3 and w.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("basis", [ChannelBasis(-30, 30, 12), ChannelBasis(0, 1, 5), ChannelBasis(-2.5, 7.0, 40)])
def test_decoding_a_single_encoded_value_returns_it(basis):
    rng = np.random.default_rng(0)
    for x in rng.uniform(basis.lo, basis.hi, 50):
        t, mass = decode(encode(x, basis))
        assert basis.from_channel(t) == pytest.approx(x, abs=1e-9 * (basis.hi - basis.lo))
        assert mass == pytest.approx(1.0)


def test_values_outside_the_range_are_clipped_to_its_ends():
    basis = ChannelBasis(0.0, 10.0, 8)
    assert basis.from_channel(decode(encode(25.0, basis))[0]) == pytest.approx(10.0)
    assert basis.from_channel(decode(encode(-3.0, basis))[0]) == pytest.approx(0.0)


def test_encoded_gaussian_density_decodes_to_its_mean():
    basis = ChannelBasis(-20, 20, 15)
    mean, sd = 4.2, 2.0
    w = encode_density(lambda x: np.exp(-0.5 * ((x - mean) / sd) ** 2) / (sd * np.sqrt(2 * np.pi)), basis)
    assert w.sum() == pytest.approx(1.0, abs=1e-6)
    assert basis.from_channel(decode(w)[0]) == pytest.approx(mean, abs=0.05 * basis.spacing)
    # a narrow density encodes like its mean
    narrow = encode_density(lambda x: np.exp(-0.5 * ((x - mean) / 0.1) ** 2) / (0.1 * np.sqrt(2 * np.pi)), basis)
    assert np.allclose(narrow, encode(mean, basis), atol=0.01)


def test_samples_encode_to_their_parzen_average_and_modes_are_found():
    basis = ChannelBasis(0, 100, 25)
    samples = np.r_[np.full(6, 20.0), np.full(4, 71.0)]
    w = encode_samples(samples, basis)
    assert np.allclose(w, encode(samples, basis).mean(axis=0))
    modes = decode_modes(w, threshold=0.2)
    assert len(modes) == 2
    assert basis.from_channel(modes[0][0]) == pytest.approx(20.0) and modes[0][1] == pytest.approx(0.6)
    assert basis.from_channel(modes[1][0]) == pytest.approx(71.0) and modes[1][1] == pytest.approx(0.4)
    assert len(decode_modes(w, threshold=0.5)) == 1


def test_nd_decoding_by_local_marginalisation():
    bases = [ChannelBasis(0, 320, 20), ChannelBasis(0, 240, 16)]
    W = encode_nd([[101.5, 37.25]], bases)
    assert W.shape == (20, 16) and W.sum() == pytest.approx(1.0)
    t, mass = decode_nd(W)
    assert [b.from_channel(v) for b, v in zip(bases, t)] == pytest.approx([101.5, 37.25])
    assert mass == pytest.approx(1.0)
    W2 = encode_nd([[50, 50], [250, 200]], bases, weights=[0.7, 0.3])
    modes = decode_nd_modes(W2, threshold=0.1)
    assert len(modes) == 2
    assert [b.from_channel(v) for b, v in zip(bases, modes[1][0])] == pytest.approx([250, 200])
    # a 3-D tensor too
    b3 = [ChannelBasis(0, 10, 8)] * 3
    t3, _ = decode_nd(encode_nd([[1.0, 5.5, 9.0]], b3))
    assert [b.from_channel(v) for b, v in zip(b3, t3)] == pytest.approx([1.0, 5.5, 9.0])


def test_update_is_the_normalised_elementwise_product():
    prior = normalized(np.array([0.1, 0.4, 0.3, 0.2]))
    h = np.array([1.0, 0.5, 0.0, 2.0])
    post, evidence = cbt_update(prior, h)
    assert evidence == pytest.approx(h @ prior)
    assert np.allclose(post, h * prior / (h @ prior))
    kept, zero = cbt_update(prior, np.zeros(4))  # nothing the prior allows: the prior stays
    assert zero == 0.0 and np.allclose(kept, prior)
    assert np.allclose(channel_product(prior, prior, "sqrt"), prior)  # sqrt product of equal encodings
    with pytest.raises(ValueError):
        channel_product(prior, h, "bogus")


def test_embedded_predict_equals_the_explicit_first_order_matrix():
    rng = np.random.default_rng(1)
    for order in (1, 2, 3):
        G = rng.random((5,) * (order + 1))
        G /= G.sum(axis=0, keepdims=True)
        W = normalized(rng.random((5,) * order))
        F = embedded_matrix(G)
        assert F.shape == (5 ** order, 5 ** order)
        assert np.allclose(F.sum(axis=0), 1.0)  # column-stochastic
        assert np.allclose(embedded_predict(W, G).ravel(), normalized(F @ W.ravel()))


def test_shift_matrix_translates_mass():
    S = shift_matrix(10, 2.0)
    assert np.allclose(S.sum(axis=0), 1.0)
    w = np.zeros(10)
    w[3] = 1.0
    assert np.argmax(S @ w) == 5
    half = shift_matrix(10, -1.5) @ w
    assert half[2] == pytest.approx(0.5) and half[1] == pytest.approx(0.5)


def test_displacement_model_on_a_position_grid():
    d_basis = ChannelBasis(-0.6, 0.6, 15)
    D = random_walk_displacement(d_basis, 0.1, order=2)
    pos = ChannelBasis(0, 200, 40)
    G = position_conditional(D, d_basis, pos, scale=30.0)
    assert G.shape == (40, 40, 40) and np.allclose(G.sum(axis=0), 1.0)
    assert np.argmax(G[:, 17, 12]) == 17  # a random walk stays put whatever the previous step
    W = diagonal_history(encode(100.0, pos), 2)
    assert pos.from_channel(decode(embedded_predict(W, G).sum(axis=1))[0]) == pytest.approx(100.0, abs=0.5)


def test_mean_field_update_keeps_the_associated_detection():
    bases = [ChannelBasis(0, 100, 20), ChannelBasis(0, 100, 20)]
    W = [np.full((20, 20), 1 / 400), np.full((20, 20), 1 / 400)]
    h = product_likelihood([[30, 70], [80, 20]], bases, weights=[1.0, 0.2], clutter=0.0)
    W_new, post, evidence = mean_field_update(W, h)
    assert evidence > 0 and post.sum() == pytest.approx(1.0)
    t, _ = decode_nd(post)  # the 2-D posterior keeps (30, 70) together, no ghost at (30, 20)
    assert [b.from_channel(v) for b, v in zip(bases, t)] == pytest.approx([30, 70], abs=1e-6)
    assert all(w.sum() == pytest.approx(1.0) for w in W_new)
