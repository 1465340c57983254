"""The graph-cut inlier selection returns the known labelling on toy graphs."""

import numpy as np

from vidtrack.learn.graphcut import min_cut_labels, select_inliers


def test_min_cut_without_pairwise_follows_the_unaries():
    fg = np.array([0.1, 2.0, 0.3, 5.0])
    bg = np.array([1.0, 0.5, 0.9, 0.2])
    labels = min_cut_labels(fg, bg, np.zeros((0, 2), int), np.zeros(0))
    assert labels.tolist() == [True, False, True, False]


def test_strong_pairwise_flips_a_weak_node_to_its_neighbours_label():
    # chain 0-1-2: nodes 0 and 2 strongly inlier, node 1 weakly outlier
    fg = np.array([0.0, 1.0, 0.0])
    bg = np.array([5.0, 0.6, 5.0])
    pairs = np.array([[0, 1], [1, 2]])
    weak = min_cut_labels(fg, bg, pairs, np.array([0.1, 0.1]))
    strong = min_cut_labels(fg, bg, pairs, np.array([1.0, 1.0]))
    assert weak.tolist() == [True, False, True]
    assert strong.tolist() == [True, True, True]


def test_cut_energy_is_minimal_on_a_random_toy_graph():
    rng = np.random.default_rng(0)
    n = 8
    fg, bg = rng.uniform(0, 2, n), rng.uniform(0, 2, n)
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < 0.4])
    w = rng.uniform(0, 1, len(pairs))
    labels = min_cut_labels(fg, bg, pairs, w)

    def energy(lab):
        return (np.sum(np.where(lab, fg, bg)) + np.sum(w * (lab[pairs[:, 0]] != lab[pairs[:, 1]])))

    brute = min(energy(np.array([(k >> i) & 1 for i in range(n)], bool)) for k in range(2 ** n))
    assert abs(energy(labels) - brute) < 1e-9


def test_nodes_outside_the_bag_are_outliers():
    scores = np.array([2.0, 2.0, 2.0, -2.0])
    feats = np.eye(4)
    pairs = np.array([[0, 1], [1, 2], [2, 3]])
    inl = select_inliers(scores, feats, pairs, np.ones(3), np.array([True, True, False, True]))
    assert inl.tolist() == [True, True, False, False]
