"""Inlier selection as a binary graph cut (PyMaxflow) over a superpixel adjacency graph.

*Multiple Instance Filtering* (Wnuk & Soatto), sec. 2: instead of the NP-hard
integer program of eq. (5), the inlier labelling inside the positive bag is
the minimum of a pairwise energy::

    E(eps) = sum_i U_i(eps_i) + sum_{(i,j) adjacent} V_ij [eps_i != eps_j]

with unary terms from the SVM scores and pairwise terms rewarding
appearance consistency, solved exactly by a min cut (Boykov & Kolmogorov).
"""

from __future__ import annotations

import maxflow
import numpy as np


def min_cut_labels(unary_fg: np.ndarray, unary_bg: np.ndarray, pairs: np.ndarray,
                   pair_weights: np.ndarray) -> np.ndarray:
    """Exact minimiser of a binary submodular energy.

    Parameters
    ----------
    unary_fg, unary_bg
        ``(N,)`` non-negative costs of labelling node ``i`` inlier / outlier.
    pairs
        ``(E, 2) int`` node index pairs.
    pair_weights
        ``(E,)`` non-negative cost paid when the two nodes get different labels.

    Returns
    -------
    ``(N,) bool``: True for inliers (the source side of the cut).
    """
    n = len(unary_fg)
    if n == 0:
        return np.zeros(0, dtype=bool)
    g = maxflow.Graph[float](n, max(len(pairs), 1))
    nodes = g.add_nodes(n)
    # source = inlier: cutting the sink edge (cap unary_fg) labels i inlier, the
    # source edge (cap unary_bg) labels it outlier
    g.add_grid_tedges(np.asarray(nodes), np.asarray(unary_bg, float), np.asarray(unary_fg, float))
    for (i, j), wgt in zip(np.asarray(pairs, dtype=np.int64).tolist(), np.asarray(pair_weights, float).tolist()):
        if wgt > 0:
            g.add_edge(i, j, wgt, wgt)
    g.maxflow()
    return ~np.asarray(g.get_grid_segments(np.asarray(nodes)), dtype=bool)


def svm_unaries(scores: np.ndarray, *, slope: float = 2.0, weights: np.ndarray | None = None):
    """Unary costs from SVM scores: ``U(1) = -log p``, ``U(0) = -log(1 - p)``, ``p = sigmoid(slope s)``.

    ``weights`` (e.g. relative superpixel areas) scale both costs.
    """
    z = slope * np.asarray(scores, float)
    fg = np.logaddexp(0.0, -z)  # -log sigmoid(z)
    bg = np.logaddexp(0.0, z)   # -log(1 - sigmoid(z))
    if weights is not None:
        fg, bg = fg * weights, bg * weights
    return fg, bg


def appearance_weights(features: np.ndarray, pairs: np.ndarray, lengths: np.ndarray, *,
                       beta: float = 1.0) -> np.ndarray:
    """Pairwise terms ``beta * l_ij / mean(l) * exp(-||f_i - f_j||^2 / (2 sigma^2))``.

    ``sigma^2`` is the mean squared descriptor distance over the edges
    (GrabCut's contrast-adaptive choice), ``l_ij`` the shared boundary length.
    """
    if len(pairs) == 0:
        return np.zeros(0)
    diff = features[pairs[:, 0]] - features[pairs[:, 1]]
    d2 = np.einsum("ij,ij->i", diff, diff)
    sigma2 = max(float(d2.mean()), 1e-12)
    return beta * (lengths / max(float(lengths.mean()), 1e-12)) * np.exp(-d2 / (2.0 * sigma2))


def select_inliers(scores: np.ndarray, features: np.ndarray, pairs: np.ndarray, lengths: np.ndarray,
                   in_bag: np.ndarray, *, slope: float = 2.0, beta: float = 1.0,
                   area: np.ndarray | None = None) -> np.ndarray:
    """Inlier superpixels: a graph cut restricted to the positive bag.

    Superpixels outside the bag are outliers by definition (sec. 2); the cut
    runs on the sub-graph of bag members.

    Returns
    -------
    ``(K,) bool`` over all superpixels.
    """
    in_bag = np.asarray(in_bag, bool)
    K = len(scores)
    out = np.zeros(K, dtype=bool)
    members = np.flatnonzero(in_bag)
    if len(members) == 0:
        return out
    index = -np.ones(K, dtype=np.int64)
    index[members] = np.arange(len(members))
    keep = in_bag[pairs[:, 0]] & in_bag[pairs[:, 1]] if len(pairs) else np.zeros(0, bool)
    sub_pairs = index[pairs[keep]] if len(pairs) else np.zeros((0, 2), np.int64)
    wts = appearance_weights(features, pairs[keep], lengths[keep], beta=beta) if len(pairs) else np.zeros(0)
    weights = None
    if area is not None:
        a = np.asarray(area, float)[members]
        weights = a / max(float(a.mean()), 1e-12)
    fg, bg = svm_unaries(np.asarray(scores)[members], slope=slope, weights=weights)
    out[members] = min_cut_labels(fg, bg, sub_pairs, wts)
    return out
