"""``FrameTruth.validate``: a truth that cannot belong to its problem is refused, naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench import Problem
from assocbench.association.truth import FrameTruth


def problem(n: int = 3, m: int = 4) -> Problem:
    """``n`` candidates (map ids 10, 11, ...) and ``m`` features in the plane."""
    return Problem(np.zeros((m, 2)), np.repeat(np.eye(2)[None], m, 0), np.ones((n, 2)), np.eye(2 * n),
                   landmark_ids=np.arange(10, 10 + n))


def truth(labels, association, visible=(True, True, True)) -> FrameTruth:
    return FrameTruth(np.array(labels, dtype=np.int64), np.array(association, dtype=np.int64), np.array(visible))


def test_a_consistent_truth_passes():
    """Two features of one landmark (a wall cut in two) may carry its id; the truth pairs one."""
    t = truth([10, -1, 12, 12], [0, -1, 3])
    assert t.validate(problem()) is t


@pytest.mark.parametrize("bad,message", [
    (truth([0, 0, 0, 0], [0, 0, 0]), "association pairs feature 0 with more than one candidate"),
    (truth([10, 11, 12, -1], [0, 1, 4]), "association pairs a candidate with feature 4, outside -1..3"),
    (truth([10, 11, 12, -1], [0, 1, -2]), "association pairs a candidate with feature -2, outside -1..3"),
    (truth([10, 11, 12], [0, 1, 2]), r"feature_labels has shape \(3,\), expected \(4,\)"),
    (truth([10, 11, 12, -1], [0, 1]), r"association has shape \(2,\), expected \(3,\)"),
    (truth([10, 11, 12, -1], [0, 1, 2], [True, True]), r"visible has shape \(2,\), expected \(3,\)"),
    (FrameTruth(np.array([10, 11, 12, -1]), np.array([0.0, 1.0, 2.0]), np.ones(3, bool)), "association must be integer"),
    (FrameTruth(np.array([10, 11, 12, -1]), np.array([0, 1, 2]), np.ones(3)), "visible must be bool"),
    (truth([10, 11, 12, -3], [0, 1, 2]), "feature_labels holds -3"),
    (truth([10, 12, 11, -1], [0, 1, 2]), "association pairs candidate 1 .landmark 11. with feature 1, which is labelled 12"),
    (truth([10, 11, 12, -1], [0, 1, -1]), "association leaves candidate 2 unpaired, but feature 2 is labelled its landmark 12"),
])
def test_an_impossible_truth_is_refused_naming_the_field(bad, message):
    """Every landmark's true feature 0 (a plugin track's bug) was scored: recall 0.88, status ok."""
    with pytest.raises(ValueError, match=f"FrameTruth.{message}"):
        bad.validate(problem())
