"""MNN: its one compiled call (gate, then the greedy) is the gate's pairs through ``greedy_pairs``."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench import make_associator
from assocbench.association.compatibility import gated_pairs
from assocbench.associators.base import greedy_pairs
from assocbench.models.synthetic import range_bearing_problem
from assocbench.tracks.camera.synthetic import camera_problem


@pytest.mark.parametrize("confidence", [0.5, 0.99])
def test_mnn_is_the_greedy_on_the_gated_pairs(confidence):
    mnn = make_associator("mnn", confidence=confidence)
    problems = [range_bearing_problem(np.random.default_rng(s), n=n)[0] for s, n in ((0, 10), (1, 40), (2, 160))]
    problems += [camera_problem(np.random.default_rng(s))[0] for s in range(3)]
    for p in problems:
        feats, lms, nis, _ = gated_pairs(p, confidence)
        want = greedy_pairs(feats, lms, nis, p.m, p.n)
        got = mnn.associate(p)
        assert got.dtype == np.int64 and np.array_equal(got, want)
        assert np.sum(got >= 0) > 0
