"""The compatibility math against independent textbook evaluations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from assocbench.association import compatibility as C
from problems import random_problem, reference_joint, reference_surprisal


@pytest.mark.parametrize("d,angular", [(2, ()), (3, ()), (2, (0,))])
def test_pairwise_nis_and_loglik_match_direct_formula(rng, d, angular):
    for _ in range(20):
        p = random_problem(rng, n=int(rng.integers(1, 6)), m=int(rng.integers(1, 7)), d=d, angular=angular)
        nis, _ = C.pairwise_nis(p)
        loglik = C.pairwise_log_likelihood(p)
        for i in range(p.m):
            for j in range(p.n):
                a = np.full(p.n, -1)
                a[j] = i
                ref_nis, ref_ll = reference_joint(p, a)
                assert nis[i, j] == pytest.approx(ref_nis, rel=1e-9, abs=1e-9)
                assert loglik[i, j] == pytest.approx(ref_ll, rel=1e-9, abs=1e-9)


def test_joint_nis_surprisal_and_incremental_factor_match_direct_formula(rng):
    for _ in range(60):
        p = random_problem(rng, n=int(rng.integers(1, 7)), m=int(rng.integers(1, 8)))
        k = min(p.n, p.m)
        a = np.full(p.n, -1)
        a[rng.permutation(p.n)[:k]] = rng.permutation(p.m)[:k]
        a[rng.uniform(size=p.n) < 0.3] = -1
        ref_nis, _ = reference_joint(p, a)
        assert C.joint_nis(p, a) == pytest.approx(ref_nis, rel=1e-9, abs=1e-9)
        assert C.surprisal(p, a) == pytest.approx(reference_surprisal(p, a), rel=1e-9, abs=1e-9)
        f = C.JointFactor(p)
        for j in np.flatnonzero(a >= 0):
            f.push(a[j], j)
        assert f.nis == pytest.approx(ref_nis, rel=1e-9, abs=1e-9)
        nis, logdet, _ = C.joint_terms(p, a)
        assert f.logdet == pytest.approx(logdet, rel=1e-9, abs=1e-9)


def test_gates_are_chi_square_quantiles(rng):
    p = random_problem(rng, n=4, m=5)
    nis, _ = C.pairwise_nis(p)
    assert np.array_equal(C.individually_compatible(p, 0.95, nis), nis <= chi2.ppf(0.95, 2))
    a = np.array([0, 1, -1, -1])
    assert C.jointly_compatible(p, a, 0.95) == (C.joint_nis(p, a) <= chi2.ppf(0.95, 4))
    with pytest.raises(ValueError, match="confidence"):
        C.chi2_threshold(2, 1.5)


def test_angles_wrap_into_minus_pi_pi():
    y = C.wrap_angles(np.array([[3.0, 2 * np.pi - 0.1], [0.5, -np.pi - 0.2]]), (1,))
    assert y[0, 1] == pytest.approx(-0.1)
    assert y[1, 1] == pytest.approx(np.pi - 0.2)
    assert y[0, 0] == 3.0
