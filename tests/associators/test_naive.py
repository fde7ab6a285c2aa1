"""The GMU project's naive association: a Mahalanobis-distance threshold, feature by feature."""

from __future__ import annotations

import numpy as np

from assocbench.association.problem import Problem
from assocbench.associators.registry import make_associator


def _problem(z, zhat):
    z, zhat = np.asarray(z, float), np.asarray(zhat, float)
    return Problem(z, np.repeat(np.eye(2)[None], len(z), axis=0), zhat, np.zeros((2 * len(zhat),) * 2))


def test_threshold_is_a_mahalanobis_distance_in_sigma_units():
    """With S = I the distance is Euclidean: 3.9 σ pairs at threshold 4, 4.1 σ does not, and 16 takes both."""
    p = _problem([[3.9, 0.0], [0.0, 104.1]], [[0.0, 0.0], [0.0, 100.0]])
    assert make_associator("naive").associate(p).tolist() == [0, -1]
    assert make_associator("naive", threshold=16).associate(p).tolist() == [0, 1]


def test_the_first_feature_wins_a_landmark_even_when_a_later_one_is_closer():
    """Feature 0 at 2 σ takes the landmark; feature 1 at 0.1 σ finds it taken (Mahalanobis nearest neighbour would
    pair feature 1). That order dependence is what the project's naive method does."""
    p = _problem([[2.0, 0.0], [0.1, 0.0]], [[0.0, 0.0]])
    assert make_associator("naive").associate(p).tolist() == [0]
    assert make_associator("mnn").associate(p).tolist() == [1]
