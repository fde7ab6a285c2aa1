"""Pairwise "same landmark" scores (scoring/pairwise.py): a duplicate lowers recall, a merge precision."""

from __future__ import annotations

import math

import pytest

from assocbench.scoring.pairwise import same_landmark_scores


@pytest.mark.parametrize("entries,labels,precision,recall", [
    ([0, 0, 0, 1, 1], [5, 5, 5, 6, 6], 1.0, 1.0),          # every sighting on its landmark
    ([0, 0, 2, 1, 1], [5, 5, 5, 6, 6], 1.0, 2 / 4),        # landmark 5 mapped twice: 1 of its 3 pairs kept
    ([0, 0, 0, 0, 0], [5, 5, 5, 6, 6], 4 / 10, 1.0),       # 5 and 6 merged: 4 of 10 pairs true
    ([0, 0, -1, 0], [5, 5, 5, -1], 1 / 3, 1 / 3),          # a clutter sighting put on 5; one of 5's left out
])
def test_pair_counts(entries, labels, precision, recall):
    scores = same_landmark_scores(entries, labels)
    assert scores["pair_precision"] == pytest.approx(precision) and scores["pair_recall"] == pytest.approx(recall)


def test_nothing_to_count_is_nan_not_one():
    scores = same_landmark_scores([0, 1, -1], [5, 6, 7])
    assert math.isnan(scores["pair_precision"]) and math.isnan(scores["pair_recall"])
