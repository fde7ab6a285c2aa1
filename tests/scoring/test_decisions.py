"""What a method decided about each feature (``scoring.decisions``): every kind, from a hand-made frame."""

from __future__ import annotations

import numpy as np

from assocbench.scoring.decisions import DECISIONS, feature_decisions


def test_each_feature_gets_the_decision_its_truth_and_pairing_make():
    # candidates: map ids 10, 11, 12; features 0..6
    landmark_ids = np.array([10, 11, 12])
    labels = np.array([10, 11, 10, 12, -1, -1, 13])   # 2: a second piece of landmark 10; 6: a landmark not predicted
    real = np.array([True, True, True, True, True, False, True])   # 4: a landmark not in the map; 5: clutter
    association = np.array([0, 5, -1])   # 10 <- feature 0 (right), 11 <- feature 5 (clutter paired: wrong)
    got = feature_decisions(landmark_ids, labels, association, real)
    assert got == ["right", "missed", "also", "missed", "new", "wrong", "new"]
    assert set(got) <= set(DECISIONS)


def test_a_pairing_with_another_landmark_is_wrong_and_leaves_its_own_missed():
    got = feature_decisions(np.array([1, 2]), np.array([1, 2]), np.array([1, 0]), np.array([True, True]))
    assert got == ["wrong", "wrong"]
    got = feature_decisions(np.array([1, 2]), np.array([1, 2]), np.array([-1, -1]), np.array([True, True]))
    assert got == ["missed", "missed"]


def test_an_unpaired_unreal_feature_is_clutter():
    assert feature_decisions(np.array([], np.int64), np.array([-1]), np.array([], np.int64), np.array([False])) == [
        "clutter"]


def test_every_decision_has_a_colour_and_words_in_the_pictures_key():
    from assocbench.tracks.plane_view import FEATURE_KINDS, PlaneFrame

    assert set(DECISIONS) <= set(FEATURE_KINDS)
    assert PlaneFrame.__dataclass_fields__["kinds"].default == DECISIONS
