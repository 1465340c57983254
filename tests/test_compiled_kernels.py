"""The Numba-compiled kernels against what they replace: SLIC, HOG histograms, colour bins."""

import cv2
import numpy as np
import pytest
from scipy import ndimage

from vidtrack.measure import superpixels as sp
from vidtrack.measure.colour_model import colour_bins
from vidtrack.measure.features import orientation_cells
from vidtrack.measure.slic import _kmeans, _seeds, slic


def _two_regions(h=60, w=90, edge=37, seed=0):
    """A noisy image, blue left of column ``edge``, orange right of it."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.uint8)
    img[:, :edge] = (200, 80, 40)
    img[:, edge:] = (30, 140, 230)
    return np.clip(img.astype(int) + rng.integers(-12, 13, img.shape), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("implementation", ["numba", "opencv"])
def test_superpixels_are_compact_connected_and_follow_a_colour_edge(implementation):
    """Both implementations: labels 0..K-1, about (h/S)(w/S) of them, each 4-connected; the compiled one's follow the edge."""
    img = _two_regions()
    labels = sp.slic_labels(img, region_size=8, ruler=10.0, iterations=4, implementation=implementation)
    K = int(labels.max()) + 1
    assert labels.shape == img.shape[:2] and labels.dtype == np.int32
    assert np.array_equal(np.unique(labels), np.arange(K))          # every label 0..K-1 used
    assert 0.5 * (60 / 8) * (90 / 8) <= K <= 1.5 * (60 / 8) * (90 / 8)
    left = np.zeros(img.shape[:2], bool)
    left[:, :37] = True
    for k in range(K):
        region = labels == k
        assert ndimage.label(region)[1] == 1                          # one 4-connected piece
        share = left[region].mean()
        if implementation == "numba":   # OpenCV's merges thin strips at the edge across it (2-4 of ~75 here)
            assert share < 0.05 or share > 0.95                      # none straddles the edge


def test_small_components_are_merged_into_a_neighbour():
    lab = cv2.cvtColor(_two_regions(seed=3), cv2.COLOR_BGR2Lab)
    lab[20:22, 50:52] = (0, 128, 128)                                # a 2x2 speck, far from both colours
    labels = slic(lab, region_size=8, ruler=10.0, iterations=4, min_size_percent=25.0)
    sizes = np.bincount(labels.ravel())
    assert sizes.min() >= 0.25 * 64 or np.argmin(sizes) == labels[0, 0]   # only the first may stay small
    no_merge = slic(lab, region_size=8, ruler=10.0, iterations=4, min_size_percent=0.0)
    assert no_merge.max() >= labels.max()


def test_kmeans_assigns_each_pixel_to_the_nearest_centre_within_reach():
    """One iteration of the compiled k-means against eq. 3 evaluated with numpy: every pixel gets a centre
    within ``S`` (rounded) of it in x and y whose distance is the smallest of all those centres' (to float32
    rounding: the compiled loop may sum the terms in another order)."""
    rng = np.random.default_rng(2)
    field = cv2.resize(rng.integers(0, 255, (9, 13, 3), dtype=np.uint8), (143, 101), interpolation=cv2.INTER_CUBIC)
    lab = cv2.cvtColor(field, cv2.COLOR_BGR2Lab).astype(np.float32)
    step, ruler = 11.0, 10.0
    centres = _seeds(lab, step)
    labels = _kmeans(lab, centres.copy(), step, ruler, 1)
    h, w = lab.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    reach = int(step + 0.5)
    cx, cy = centres[:, 3][:, None, None], centres[:, 4][:, None, None]
    d = (np.sum((lab[None] - centres[:, None, None, :3]) ** 2, axis=3)
         + (ruler / step) ** 2 * ((xs - cx) ** 2 + (ys - cy) ** 2))                  # (K, h, w), eq. 3
    within = (np.abs(xs - cx.astype(int)) <= reach) & (np.abs(ys - cy.astype(int)) <= reach)
    d = np.where(within, d, np.inf)
    best = d.min(axis=0)
    chosen = np.take_along_axis(d, labels[None].astype(np.int64), axis=0)[0]
    assert np.all(np.isfinite(best))
    assert np.allclose(chosen, best, rtol=1e-5, atol=1e-3)
    assert np.mean(labels == d.argmin(axis=0)) > 0.99


def test_the_two_implementations_agree_on_a_real_region():
    rng = np.random.default_rng(1)
    # a smooth random colour field: both must give about as many superpixels, with similar boundaries
    field = cv2.resize(rng.integers(0, 255, (8, 12, 3), dtype=np.uint8), (156, 94), interpolation=cv2.INTER_CUBIC)
    a = sp.slic_labels(field, region_size=11, implementation="numba")
    b = sp.slic_labels(field, region_size=11, implementation="opencv")
    assert abs(int(a.max()) - int(b.max())) <= 0.2 * b.max()

    def boundary(labels):
        return (np.diff(labels, axis=0, prepend=labels[:1]) != 0) | (np.diff(labels, axis=1, prepend=labels[:, :1]) != 0)

    near_b = ndimage.binary_dilation(boundary(b), iterations=2)
    assert near_b[boundary(a)].mean() > 0.6                           # most boundaries within 2 px of the other's


def _orientation_cells_reference(grey, cell=4, bins=9, clip=0.2):
    """The histograms with numpy's bincount (a plain numpy reference for the compiled kernel)."""
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=1)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=1)
    mag, ang = cv2.cartToPolar(gx, gy)
    ang = np.where(ang >= np.float32(np.pi), ang - np.float32(np.pi), ang)
    pos = ang * np.float32(bins / np.pi) - np.float32(0.5)
    lo = np.floor(pos)
    frac = pos - lo
    lo = lo.astype(np.int64)
    hi = (lo + 1) % bins
    lo = lo % bins
    H, W = grey.shape
    hc, wc = H // cell, W // cell
    rows = np.minimum(np.arange(H) // cell, hc - 1)
    cols = np.minimum(np.arange(W) // cell, wc - 1)
    index = ((rows[:, None] * wc + cols[None, :]) * bins).ravel()
    m, f = mag.ravel().astype(float), frac.ravel()
    n = hc * wc * bins
    cells = (np.bincount(index + lo.ravel(), weights=m * (1 - f), minlength=n)
             + np.bincount(index + hi.ravel(), weights=m * f, minlength=n)).reshape(hc, wc, bins)
    energy = np.sum(cells ** 2, axis=2)
    padded = np.pad(energy, 1, mode="edge")
    block = padded[:-1, :-1] + padded[1:, :-1] + padded[:-1, 1:] + padded[1:, 1:]
    inv = 1.0 / np.sqrt(block + 1e-4)
    norm = 0.25 * (inv[:-1, :-1] + inv[1:, :-1] + inv[:-1, 1:] + inv[1:, 1:])
    return np.minimum(cells * norm[:, :, None], clip)


@pytest.mark.parametrize("shape", [(160, 160), (64, 98), (17 * 24, 40)])
def test_compiled_orientation_histograms_match_the_numpy_reference(shape):
    rng = np.random.default_rng(2)
    grey = cv2.GaussianBlur(rng.integers(0, 255, shape).astype(np.float32), (0, 0), 1.5)
    assert orientation_cells(grey) == pytest.approx(_orientation_cells_reference(grey), abs=1e-5)


def test_compiled_colour_bins_match_numpy():
    rng = np.random.default_rng(5)
    patch = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    for bins in (32, 16, 8):
        shift = int(np.log2(256 // bins))
        q = (patch >> shift).astype(np.int32)
        assert np.array_equal(colour_bins(patch, bins), (q[:, :, 0] * bins + q[:, :, 1]) * bins + q[:, :, 2])
