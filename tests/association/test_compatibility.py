"""The compatibility math against independent textbook evaluations."""

from __future__ import annotations

import numpy as np
import pytest
from problems import random_problem, reference_joint, reference_surprisal
from scipy.stats import chi2

from assocbench import Problem
from assocbench.association import compatibility as C
from assocbench.models.synthetic import lattice_problem, range_bearing_problem
from assocbench.tracks.camera.synthetic import camera_problem


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


def _seam_problem(rng, p):
    """``p`` with its angular dims spread over several turns (features up to ±400 rad, so the
    gate's window runs over the ±π seam) and its covariances scaled, kept correlated."""
    z, zhat = p.z.copy(), p.zhat.copy()
    for a in p.angular:
        z[:, a] = rng.uniform(-4, 4, p.m) * rng.choice([1, 100])
        zhat[:, a] = rng.uniform(-4, 4, p.n)
    scale = rng.choice([1e-4, 1e-2, 1.0])
    return Problem(z, p.R * scale, zhat, p.P * scale, volume=1.0, angular=p.angular)


def test_gate_prefilter_finds_every_pair_of_the_all_pairs_pass(rng):
    """``pairs_within`` (the sorted sweep over gate boxes) against ``pairwise_nis`` on every pair:
    the same pairs, in landmark-then-feature order, with the same NIS and log det bit for bit;
    random correlated P and R, 1-3 dims, any of them angular (also across the seam), gates
    from tight to wider than a half turn; and the synthetic problems."""
    problems = []
    for _ in range(600):
        d = int(rng.integers(1, 4))
        angular = tuple(a for a in range(d) if rng.uniform() < 0.5)
        p = random_problem(rng, n=int(rng.integers(1, 12)), m=int(rng.integers(1, 12)), d=d, angular=angular)
        problems.append(_seam_problem(rng, p) if angular and rng.uniform() < 0.5 else p)
    problems += [f(np.random.default_rng(s), n=80)[0] for s in range(3)
                 for f in (range_bearing_problem, camera_problem, lattice_problem)]
    for p in problems:
        nis, logdet = C.pairwise_nis(p)
        for c in (0.5, 0.99, 1 - 1e-9):
            limit = C.chi2_threshold(p.d, c)
            feats, lms, got_nis, got_logdet = C.pairs_within(p, limit)
            expected = np.argwhere((nis <= limit).T)         # (landmark, feature), sorted
            assert np.array_equal(lms, expected[:, 0]) and np.array_equal(feats, expected[:, 1])
            assert np.array_equal(got_nis, nis[feats, lms]) and np.array_equal(got_logdet, logdet[feats, lms])
        assert C.pairs_within(p, 1e300)[0].size == p.m * p.n    # every window wider than a whole turn


def test_the_scalar_d2_pair_test_is_the_general_one_bit_for_bit(rng):
    """``whitened_nis`` takes a scalar path for d = 2 (JCBB's forward check and dives); its
    ΔNIS, ``L22`` and ``L22⁻¹ y`` must be the general kernel's exactly (same arithmetic, same
    order), and inf where S is not definite."""
    n, m, d = 6, 7, 2
    A = rng.normal(size=(n * d, n * d))
    P = A @ A.T / (n * d)
    R = np.stack([np.diag(rng.uniform(0.01, 0.5, d)) for _ in range(m)])
    z = rng.uniform(-4.0, 4.0, (m, d))          # residuals across ±π on the wrapped dimension
    zhat = rng.uniform(-4.0, 4.0, (n, d))
    wrap = np.array([False, True])
    c = rng.normal(size=(n, d)) * 0.3
    B = rng.normal(size=(n, d, d)) * 0.4
    G = B @ np.swapaxes(B, 1, 2)                # large enough that some S are not definite
    S, y = np.empty((d, d)), np.empty(d)
    finite = 0
    for i in range(m):
        for j in range(n):
            L, w = np.empty((d, d)), np.empty(d)
            got = C.whitened_nis(P, z, zhat, R, wrap, i, j, c, G, S, y, L, w)
            L_ref, w_ref = np.empty((d, d)), np.empty(d)
            C.pair_innovation(P, z, zhat, R, wrap, i, j, c, G, S, y)
            want, det = C._whiten_det(S, y, L_ref, w_ref)
            assert got == want
            # the individual gate's (NIS, det S) in scalars: the same pair
            assert C._individual_whitened(P, z, zhat, R, wrap, i, j, c, G, S, y, np.empty((d, d)),
                                          np.empty(d)) == (want, det)
            if np.isfinite(want):
                finite += 1
                assert np.array_equal(L, L_ref) and np.array_equal(w, w_ref)
    assert 0 < finite < m * n


def test_the_scalar_d2_factor_updates_are_the_general_ones_bit_for_bit(rng):
    """``append_rows`` and ``advance_moments`` take scalar paths for d = 2 (every push of JCBB's
    search, SNN and RJC); the rows and moments they write must be the general loops' exactly,
    also where the outputs are the inputs (SNN, RJC) and where ``cols`` holds the pushed landmark
    (the ranked dive)."""
    n, d = 7, 2
    for kd in (0, 1, 4, 7):
        Mt = rng.normal(size=(n * d, n * d))
        A = rng.normal(size=(n * d, n * d))
        P = A @ A.T
        L = np.tril(rng.normal(size=(d, d))) + 3.0 * np.eye(d)
        w2 = rng.normal(size=d)
        cols = np.array([0, 2, 3, 6])
        scalar, general = Mt.copy(), Mt.copy()
        C._append_rows_2(scalar, kd, P, 3, L, cols)
        C._append_rows_any(general, kd, P, 3, L, cols)
        assert np.array_equal(scalar, general) and not np.array_equal(scalar, Mt)
        c, G = rng.normal(size=(n, d)), rng.normal(size=(n, d, d))
        outs = [(np.zeros((n, d)), np.zeros((n, d, d))) for _ in range(2)]
        C._advance_moments_2(scalar, kd, w2, cols, c, G, *outs[0])
        C._advance_moments_any(scalar, kd, w2, cols, c, G, *outs[1])
        assert all(np.array_equal(a, b) for a, b in zip(outs[0], outs[1]))
        in_place = [(c.copy(), G.copy()) for _ in range(2)]
        C._advance_moments_2(scalar, kd, w2, cols, *in_place[0], *in_place[0])
        C._advance_moments_any(scalar, kd, w2, cols, *in_place[1], *in_place[1])
        assert all(np.array_equal(a, b) for a, b in zip(in_place[0], in_place[1]))
        assert np.array_equal(in_place[0][0][cols], outs[0][0][cols])
