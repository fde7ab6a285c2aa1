"""CCDA (combined constraint data association): the binary constraint's NIS against a textbook
formula, the clique against plain brute force, the no-pose-prior property, parameters."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from problems import random_problem, reference_joint, wrap
from scipy.stats import chi2

from assocbench import Problem, UserError, make_associator, validate_association
from assocbench.association import compatibility as C
from assocbench.associators.ccda import MAX_VERTICES, correspondence_graph, swap_descent
from assocbench.associators.max_clique import max_clique, set_edge


def reference_difference_nis(p: Problem, i: int, j: int, i2: int, j2: int) -> float:
    """``Δᵀ S_Δ⁻¹ Δ`` with an explicit inverse: the textbook formula of the binary constraint."""
    d = p.d
    blk = lambda a, b: p.P[a * d:(a + 1) * d, b * d:(b + 1) * d]  # noqa: E731
    S = blk(j, j) + blk(j2, j2) - blk(j, j2) - blk(j2, j) + p.R[i] + p.R[i2]
    y = wrap((p.z[i] - p.zhat[j]) - (p.z[i2] - p.zhat[j2]), p.angular)
    return float(y @ np.linalg.inv(S) @ y)


def reference_graph(p: Problem, confidence: float, unary: bool):
    """Vertices (feature, landmark) and an edge test, from the explicit-inverse formulas."""
    gate = chi2.ppf(confidence, p.d)
    vertices = []
    for i, j in itertools.product(range(p.m), range(p.n)):
        single = np.full(p.n, -1)
        single[j] = i
        if not unary or reference_joint(p, single)[0] <= gate:
            vertices.append((i, j))
    edges = {(a, b) for a, b in itertools.combinations(vertices, 2)
             if a[0] != b[0] and a[1] != b[1] and reference_difference_nis(p, *a, *b) <= gate}
    return vertices, lambda a, b: (a, b) in edges or (b, a) in edges


def brute_force_clique_size(p: Problem, vertices, edge) -> int:
    """Largest set of vertices, one feature per landmark and distinct features, all joined: every
    choice of landmarks (largest first) and of a feature for each, by itertools."""
    by_landmark = {j: [i for i, jj in vertices if jj == j] for j in range(p.n)}
    usable = [j for j in range(p.n) if by_landmark[j]]
    for k in range(len(usable), 0, -1):
        for lms in itertools.combinations(usable, k):
            for feats in itertools.product(*(by_landmark[j] for j in lms)):
                pairs = list(zip(feats, lms))
                if len(set(feats)) == k and all(edge(a, b) for a, b in itertools.combinations(pairs, 2)):
                    return k
    return 0


def pairings(out: np.ndarray) -> list[tuple[int, int]]:
    return [(int(out[j]), int(j)) for j in np.flatnonzero(out >= 0)]


@pytest.mark.parametrize("d,angular", [(1, ()), (2, ()), (3, ()), (2, (1,))])
def test_difference_nis_matches_explicit_inverse(rng, d, angular):
    for _ in range(10):
        p = random_problem(rng, n=int(rng.integers(2, 6)), m=int(rng.integers(2, 7)), d=d, angular=angular)
        a = np.array([(i, j) for i in range(p.m) for j in range(p.n)])
        b = a[rng.permutation(len(a))]
        got = C.difference_nis(p, a, b)
        ref = [reference_difference_nis(p, *x, *y) for x, y in zip(a, b)]
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)


def test_difference_nis_ignores_an_error_common_to_both_predictions(rng):
    p = random_problem(rng, n=4, m=4)
    shifted = Problem(p.z + [50.0, -80.0], p.R, p.zhat, p.P, volume=p.volume)
    a, b = np.array([[0, 1], [2, 3]]), np.array([[1, 2], [3, 0]])
    np.testing.assert_allclose(C.difference_nis(shifted, a, b), C.difference_nis(p, a, b), rtol=1e-9)


@pytest.mark.parametrize("unary", [True, False])
def test_clique_is_maximum_and_pairwise_consistent(rng, unary):
    """Small problems: the answer is a clique of the correspondence graph (explicit-inverse tests)
    as large as the brute-force maximum clique."""
    gate = chi2.ppf(0.99, 2)
    for trial in range(25):
        n, m = (int(rng.integers(1, 7)), int(rng.integers(1, 8))) if unary else (int(rng.integers(1, 5)), int(rng.integers(1, 6)))
        p = random_problem(rng, n=n, m=m, angular=(1,) if trial % 4 == 0 else ())
        ccda = make_associator("ccda", unary=unary)
        out = validate_association(ccda.associate(p), p)
        vertices, edge = reference_graph(p, 0.99, unary)
        chosen = pairings(out)
        assert set(chosen) <= set(vertices), trial          # the unary test, when on
        for a, b in itertools.combinations(chosen, 2):      # the binary test
            assert reference_difference_nis(p, *a, *b) <= gate, trial
        assert len(chosen) == brute_force_clique_size(p, vertices, edge), trial
        assert ccda.info["proven_optimal"] and not ccda.info["timed_out"]


def test_ranges_and_bearings_give_pairwise_consistent_sets():
    from assocbench.models.synthetic import range_bearing_problem

    for seed in range(4):
        p, _ = range_bearing_problem(np.random.default_rng(seed), n=30)
        out = make_associator("ccda").associate(p)
        chosen = np.array(pairings(out))
        nis = C.pairwise_nis(p)[0]
        assert np.all(nis[chosen[:, 0], chosen[:, 1]] <= chi2.ppf(0.99, 2))
        a, b = zip(*itertools.combinations(chosen.tolist(), 2))
        assert np.all(C.difference_nis(p, np.array(a), np.array(b)) <= chi2.ppf(0.99, 2))


def offset_problem(seed: int = 7, offset=(150.0, 40.0)) -> tuple[Problem, np.ndarray]:
    """Landmarks scattered on a 100 x 100 plane, σ 1 each and uncorrelated, measured with every
    prediction off by the same ``offset`` (far outside the individual gate, and beyond the
    plane, so that no feature falls near any landmark): a pose error the prior knows nothing
    about. Two landmarks are not seen, two features are clutter (in the shifted plane)."""
    rng = np.random.default_rng(seed)
    n = 10
    zhat = rng.uniform(0, 100, (n, 2))
    seen = np.arange(2, n)
    z = np.vstack([zhat[seen] + offset + rng.normal(0, 0.3, (len(seen), 2)),
                   rng.uniform(0, 100, (2, 2)) + offset])
    perm = rng.permutation(len(z))
    z = z[perm]
    truth = np.full(n, -1)
    truth[seen] = np.argsort(perm)[:len(seen)]
    R = np.repeat((0.3**2 * np.eye(2))[None], len(z), 0)
    return Problem(z, R, zhat, np.eye(2 * n), volume=1e4), truth


def test_without_the_unary_gate_no_pose_prior_is_needed():
    p, truth = offset_problem()
    nis = C.pairwise_nis(p)[0]
    assert not np.any(C.individually_compatible(p, 0.99, nis))       # the offset defeats every gate
    assert np.all(make_associator("ccda").associate(p) == -1)
    free = make_associator("ccda", unary=False)
    assert free.associate(p).tolist() == truth.tolist()
    assert free.info["vertices"] == p.m * p.n and free.info["proven_optimal"]


def test_swaps_undo_two_landmarks_trading_features():
    """The tie rule: landmarks 1 and 4 lie 0.5 apart, so the pairings with their features traded
    form a second maximum clique; from it the descent on the total binary NIS (one two-for-two
    swap) reaches the right one, whose total is zero."""
    zhat = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0], [10.5, 0.0]])
    p = Problem(zhat.copy(), np.repeat(0.05 * np.eye(2)[None], 5, 0), zhat, 0.3 * np.eye(10), volume=1e3)
    lms, feats = np.nonzero(np.ones((5, 5), bool).T)
    args = (p.P, np.ascontiguousarray(C.marginal_blocks(p)), p.z, p.zhat, p.R, C.wrap_mask(p))
    adj = correspondence_graph(*args, feats, lms, C.chi2_threshold(2, 0.99))
    vertex = {(int(i), int(j)): v for v, (i, j) in enumerate(zip(feats, lms))}
    right = sorted(vertex[(j, j)] for j in range(5))
    traded = sorted([vertex[(j, j)] for j in (0, 2, 3)] + [vertex[(4, 1)], vertex[(1, 4)]])
    joined = lambda a, b: bool((int(adj[a, b >> 6]) >> (b & 63)) & 1)  # noqa: E731
    assert all(joined(a, b) for a, b in itertools.combinations(traded, 2))
    out, swaps = swap_descent(adj, np.array(traded), *args, feats, lms)
    assert sorted(out.tolist()) == right and swaps == 1
    out, swaps = swap_descent(adj, np.array(right), *args, feats, lms)
    assert sorted(out.tolist()) == right and swaps == 0


def test_the_same_problem_gives_the_same_answer(rng):
    from assocbench.models.synthetic import range_bearing_problem

    p, _ = range_bearing_problem(np.random.default_rng(5), n=60)
    a = make_associator("ccda").associate(p)
    b = make_associator("ccda").associate(p)
    assert np.array_equal(a, b)


def test_node_budget_returns_the_best_so_far():
    from assocbench.models.synthetic import range_bearing_problem

    p, _ = range_bearing_problem(np.random.default_rng(1), n=40)
    ccda = make_associator("ccda", max_nodes=3)
    out = validate_association(ccda.associate(p), p)
    assert ccda.info["timed_out"] and not ccda.info["proven_optimal"] and ccda.info["nodes"] == 4
    assert np.sum(out >= 0) == 2       # the root and two nodes of the first dive: a clique of two


@pytest.mark.parametrize("params,match", [
    ({"confidence": 1.5}, r"params\.confidence must be a finite number in \(0, 1\), got 1\.5"),
    ({"confidence": 0}, r"params\.confidence"),
    ({"max_nodes": 0}, r"params\.max_nodes must be an integer >= 1, got 0"),
    ({"max_nodes": 2.5}, r"params\.max_nodes must be an integer"),
    ({"unary": "no"}, r"params\.unary must be true or false, got 'no'"),
    ({"gate": 3}, r"unknown parameter gate for method 'ccda': accepted are confidence, unary, max_nodes"),
])
def test_bad_parameters_give_one_line_errors(params, match):
    with pytest.raises(UserError, match=match) as err:
        make_associator("ccda", **params)
    assert "\n" not in str(err.value)


def test_a_graph_too_large_without_the_unary_gate_is_a_clear_error():
    n = m = int(np.sqrt(MAX_VERTICES)) + 1
    p = Problem(np.zeros((m, 2)), np.repeat(np.eye(2)[None], m, 0), np.zeros((n, 2)), np.eye(2 * n))
    with pytest.raises(UserError, match=r"ccda: the correspondence graph would have \d+ vertices .*use unary=True") as err:
        make_associator("ccda", unary=False).associate(p)
    assert "\n" not in str(err.value)


def reference_clique_number(neighbours: list[set]) -> int:
    """Bron-Kerbosch with pivoting: the size of a maximum clique."""
    best = 0

    def expand(size: int, cand: set, excluded: set) -> None:
        nonlocal best
        if not cand and not excluded:
            best = max(best, size)
            return
        if size + len(cand) <= best:
            return
        pivot = max(cand | excluded, key=lambda u: len(neighbours[u] & cand))
        for v in list(cand - neighbours[pivot]):
            expand(size + 1, cand & neighbours[v], excluded & neighbours[v])
            cand = cand - {v}
            excluded = excluded | {v}

    expand(0, set(range(len(neighbours))), set())
    return best


@pytest.mark.parametrize("V,density", [(12, 0.8), (70, 0.5), (150, 0.3), (200, 0.15)])
def test_max_clique_on_random_graphs(rng, V, density):
    """Against plain references: itertools on 12 vertices, Bron-Kerbosch on graphs spanning
    several 64-bit words."""
    for _ in range(5):
        adj = np.zeros((V, (V + 63) // 64), np.uint64)
        neighbours = [set() for _ in range(V)]
        for a, b in itertools.combinations(range(V), 2):
            if rng.uniform() < density:
                set_edge(adj, a, b)
                neighbours[a].add(b)
                neighbours[b].add(a)
        clique, _, timed_out = max_clique(adj, V, 10**7)
        assert not timed_out
        assert all(b in neighbours[a] for a, b in itertools.combinations(clique.tolist(), 2))
        if V <= 12:
            expected = max(k for k in range(1, V + 1) for c in itertools.combinations(range(V), k)
                           if all(b in neighbours[a] for a, b in itertools.combinations(c, 2)))
        else:
            expected = reference_clique_number(neighbours)
        assert len(clique) == expected
