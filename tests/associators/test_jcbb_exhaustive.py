"""JCBB returns exactly the hypothesis of an exhaustive search (most pairings, then lowest NIS)."""

from __future__ import annotations

import numpy as np
import pytest
from problems import exhaustive_best, random_spd

from assocbench import Problem, make_associator


def small_problem(rng, d: int = 2) -> Problem:
    """n <= 6 landmarks, m <= 7 features of dimension d: correlated P, clutter, missed detections."""
    n = int(rng.integers(1, 7))
    P = random_spd(rng, n * d, 6.0) + 4.0 * np.kron(np.ones((n, n)), np.eye(d))  # common-mode part
    zhat = rng.uniform(0, 20, (n, d))
    err = np.linalg.cholesky(P) @ rng.normal(size=n * d)
    detected = np.flatnonzero(rng.uniform(size=n) < 0.75)
    clutter = rng.uniform(0, 20, (int(rng.integers(0, 3)), d))
    z = np.vstack([zhat[detected] + err.reshape(n, d)[detected], clutter])[:7]
    z = z[rng.permutation(len(z))]
    R = np.stack([random_spd(rng, d, 0.3) for _ in range(len(z))]) if len(z) else np.zeros((0, d, d))
    return Problem(z, R, zhat, P, volume=400.0)


@pytest.mark.parametrize("block", range(6))
def test_jcbb_equals_exhaustive_search(block):
    rng = np.random.default_rng(1000 + block)
    jcbb = make_associator("jcbb", confidence=0.95)
    for _ in range(55):  # 6 blocks x 55 = 330 problems
        p = small_problem(rng)
        k, nis, expected = exhaustive_best(p, 0.95)
        got = jcbb.associate(p)
        assert int(np.sum(got >= 0)) == k
        assert got.tolist() == expected.tolist(), (got, expected)
        assert not jcbb.info["timed_out"]


@pytest.mark.parametrize("d", [1, 3])
def test_jcbb_equals_exhaustive_search_in_other_dimensions(d):
    """The factor update has a d = 2 fast path; other measurement sizes take the general one."""
    rng = np.random.default_rng(2000 + d)
    jcbb = make_associator("jcbb", confidence=0.95)
    for _ in range(40):
        p = small_problem(rng, d)
        assert jcbb.associate(p).tolist() == exhaustive_best(p, 0.95)[2].tolist()
