"""JPDA: marginals equal a plain enumeration of every joint event, BP is close (exact on trees),
the hard answer follows the marginals, the true-mass score, and clear errors for bad parameters."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from cli.test_cli import assert_one_line_error
from problems import random_problem, random_spd, reference_joint
from scipy.stats import chi2

from assocbench import Problem, UserError, make_associator
from assocbench.cli.main import main
from assocbench.scoring.metrics import true_mass

# BP (forced with max_events=1) against exact JPDA over the small problems below, measured:
# max |Δβ| 0.250 (a 2 x 2 loop, where BP leans to the likelier assignment), mean over landmarks
# of the row's max |Δβ| 0.023, hard answers equal on 123 of 124 landmarks.
BP_MAX_ERROR, BP_MEAN_ERROR, BP_AGREEMENT = 0.3, 0.03, 0.97


def crowded_problem(rng, n: int, m: int, angular=()) -> Problem:
    """Like ``random_problem`` but predictions packed into a 10 x 10 square (plus clutter around
    it), so that gates overlap and clusters hold several landmarks and cycles."""
    d = 2
    zhat = rng.uniform(0, 10, (n, d))
    if angular:
        zhat[:, 1] = rng.uniform(np.pi - 1.0, np.pi, n)        # bearings near the ±π cut
    k = min(m, n)
    z = np.vstack([zhat[rng.permutation(n)[:k]] + rng.normal(0, 1.5, (k, d)),
                   rng.uniform(-2, 12, (m - k, d))])
    if angular:
        z[:, 1] = np.mod(z[:, 1] + np.pi, 2 * np.pi) - np.pi
    R = np.stack([random_spd(rng, d, 0.3) for _ in range(m)]) if m else np.zeros((0, d, d))
    return Problem(z, R, zhat, random_spd(rng, n * d, 3.0), volume=196.0, angular=angular)


def small_problems() -> list[Problem]:
    out = []
    for seed in range(36):
        rng = np.random.default_rng(seed)
        n, m = int(rng.integers(1, 6)), int(rng.integers(1, 7))
        angular = (1,) if seed % 3 == 0 else ()
        make = crowded_problem if seed % 2 else random_problem
        out.append(make(rng, n, m, angular=angular))
    return out


def brute_force_marginals(p: Problem, p_detect: float, confidence: float, density: float) -> np.ndarray:
    """Every feasible joint event, P(θ) ∝ Π_{(i,j)∈θ} P_D N_ij / λ · Π_{j undetected} (1 - P_D P_G),
    with N_ij and the gate from explicit inverses (tests/problems.py)."""
    n, m = p.n, p.m
    like = np.zeros((m, n))
    gated = np.zeros((m, n), bool)
    for i, j in itertools.product(range(m), range(n)):
        single = np.full(n, -1)
        single[j] = i
        nis, loglik = reference_joint(p, single)
        gated[i, j] = nis <= chi2.ppf(confidence, p.d)
        like[i, j] = np.exp(loglik)
    beta = np.zeros((n, m + 1))
    options = [[-1] + [i for i in range(m) if gated[i, j]] for j in range(n)]
    for event in itertools.product(*options):
        chosen = [i for i in event if i >= 0]
        if len(set(chosen)) < len(chosen):
            continue                                           # a feature used twice
        prob = 1.0
        for j, i in enumerate(event):
            prob *= p_detect * like[i, j] / density if i >= 0 else 1 - p_detect * confidence
        for j, i in enumerate(event):
            beta[j, i] += prob                                  # column -1 is the last: undetected
    return beta / beta[0].sum() if n else beta


@pytest.mark.parametrize("params", [{}, {"p_detect": 1.0, "confidence": 0.95, "clutter_density": 0.02},
                                    {"p_detect": 0.5, "clutter_density": 1e-4}])
def test_marginals_equal_brute_force_enumeration(params):
    largest = 0
    for k, p in enumerate(small_problems()):
        jpda = make_associator("jpda", **params)
        jpda.associate(p)
        beta = jpda.info["marginals"]
        want = brute_force_marginals(p, params.get("p_detect", 0.9), params.get("confidence", 0.99),
                                     params.get("clutter_density", 1.0 / p.volume))
        assert beta.shape == (p.n, p.m + 1)
        np.testing.assert_allclose(beta, want, rtol=0, atol=1e-9, err_msg=f"problem {k}")
        np.testing.assert_allclose(beta.sum(axis=1), 1.0, rtol=0, atol=1e-12)
        assert jpda.info["exact"] and jpda.info["approximate_clusters"] == 0
        largest = max(largest, jpda.info["largest_cluster"])
    assert largest >= 4   # the enumeration met clusters of several landmarks, not just singletons


def test_belief_propagation_is_close_to_exact():
    worst, row_errors, agree, landmarks, approximated = 0.0, [], 0, 0, 0
    for p in small_problems():
        exact, bp = make_associator("jpda"), make_associator("jpda", max_events=1)
        agree += int(np.sum(exact.associate(p) == bp.associate(p)))
        landmarks += p.n
        approximated += bp.info["approximate_clusters"]
        assert bp.info["exact"] == (bp.info["clusters"] == 0)
        np.testing.assert_allclose(bp.info["marginals"].sum(axis=1), 1.0, rtol=0, atol=1e-12)
        error = np.abs(bp.info["marginals"] - exact.info["marginals"])
        worst = max(worst, float(error.max()))
        row_errors += error.max(axis=1).tolist()
    assert approximated > 30
    assert worst <= BP_MAX_ERROR and np.mean(row_errors) <= BP_MEAN_ERROR, (worst, np.mean(row_errors))
    assert agree >= BP_AGREEMENT * landmarks, (agree, landmarks)


def test_belief_propagation_leans_to_the_likelier_assignment_on_a_loop():
    """Two landmarks, two features, all four pairs gated: the 2 x 2 loop. BP keeps the ranking of
    the two crossing assignments but is more certain than exact JPDA."""
    p = Problem(np.array([[0.0, 0.0], [1.5, 0.0]]), np.repeat(0.1 * np.eye(2)[None], 2, 0),
                np.array([[0.5, 0.0], [1.2, 0.0]]), np.eye(4), volume=100.0)
    exact, bp = make_associator("jpda"), make_associator("jpda", max_events=1)
    assert exact.associate(p).tolist() == bp.associate(p).tolist() == [0, 1]
    e, b = exact.info["marginals"], bp.info["marginals"]
    assert np.all(e[:, :2] > 0.05) and b[0, 0] > e[0, 0] > 0.5 and b[1, 1] > e[1, 1] > 0.5


def chain_problem() -> Problem:
    """Landmarks at x = 0, 4, 8, 12 and features at x = 2, 6, 10 (plus one far clutter feature):
    the gate (radius ≈ 3) joins each landmark to its neighbouring features only, a path."""
    zhat = np.column_stack([[0.0, 4.0, 8.0, 12.0], np.zeros(4)])
    z = np.column_stack([[2.0, 6.3, 9.8, 40.0], [0.1, -0.2, 0.0, 0.0]])
    P = np.kron(np.eye(4), 0.8 * np.eye(2)) + 0.1   # cross-covariances JPDA must ignore
    return Problem(z, np.repeat(0.2 * np.eye(2)[None], 4, 0), zhat, P, volume=400.0)


def test_belief_propagation_is_exact_on_a_tree():
    p = chain_problem()
    exact, bp = make_associator("jpda"), make_associator("jpda", max_events=1)
    exact.associate(p)
    bp.associate(p)
    beta = exact.info["marginals"]
    assert np.count_nonzero(beta[:, :p.m]) == 6 and exact.info["largest_cluster"] == 4   # one path of 6 pairs
    assert bp.info["approximate_clusters"] == 1 and not bp.info["exact"]
    np.testing.assert_allclose(bp.info["marginals"], beta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(beta, brute_force_marginals(p, 0.9, 0.99, 1 / 400.0), rtol=0, atol=1e-12)


def test_cut_over_counts_events_and_budget():
    p = chain_problem()
    jpda = make_associator("jpda")
    jpda.associate(p)
    # matchings of a path with 6 edges: Fibonacci F(8) = 21 events
    assert jpda.info["events"] == 21 and jpda.info["clusters"] == 1
    at_budget = make_associator("jpda", max_events=21)
    at_budget.associate(p)
    assert at_budget.info["exact"] and at_budget.info["events"] == 21
    below = make_associator("jpda", max_events=20)
    below.associate(p)
    assert not below.info["exact"] and below.info["events"] == 0


def test_event_count_and_its_lower_bound():
    """The cut-over's count (a weightless walk) equals the enumeration's and the cheap lower bound
    never exceeds it (a bound too high would send an enumerable cluster to BP)."""
    from assocbench.associators.jpda_kernels import (
        _cluster,
        _components,
        count_events,
        enumerate_events,
        events_lower_bound,
    )

    clusters = 0
    for p in small_problems() + [chain_problem()]:
        gated, logr = make_associator("jpda").pair_log_weights(p)
        label, count = _components(gated)
        for c in range(count):
            lms, feats, off, nbr, lw = _cluster(gated, logr, label, c)
            events = enumerate_events(off, nbr, lw, len(feats), 10**9, np.empty((len(lms), len(feats) + 1)))
            assert count_events(off, nbr, len(feats), 10**9) == events
            assert count_events(off, nbr, len(feats), events - 1) == -1
            assert events_lower_bound(off, nbr, len(feats)) <= events
            clusters += 1
    assert clusters > 50


def test_same_problem_same_marginals_bit_for_bit():
    p = crowded_problem(np.random.default_rng(5), 5, 6)
    for params in ({}, {"max_events": 1}):
        a, b = make_associator("jpda", **params), make_associator("jpda", **params)
        assert a.associate(p).tolist() == b.associate(p).tolist()
        assert np.array_equal(a.info["marginals"], b.info["marginals"])


def test_hard_answer_follows_the_marginals():
    without_conflict = 0
    for p in small_problems():
        jpda = make_associator("jpda")
        out = jpda.associate(p)
        beta = jpda.info["marginals"]
        free = set(range(p.m)) - set(out.tolist())
        for j, i in enumerate(out):
            if i >= 0:
                assert beta[j, i] > beta[j, -1]
            else:   # left out: no free feature it prefers to being undetected
                assert all(beta[j, f] <= beta[j, -1] for f in free)
        best = np.argmax(beta, axis=1)
        want = np.where(best < p.m, best, -1)
        if len(set(want[want >= 0].tolist())) == int(np.sum(want >= 0)):
            without_conflict += 1   # no two landmarks want one feature: each takes its argmax
            assert out.tolist() == want.tolist()
    assert without_conflict >= 20


def test_marginals_of_empty_problems():
    for m, n in [(0, 3), (3, 0), (0, 0)]:
        p = Problem(np.zeros((m, 2)), np.repeat(np.eye(2)[None], m, 0), np.zeros((n, 2)), np.eye(2 * n))
        jpda = make_associator("jpda")
        assert np.all(jpda.associate(p) == -1)
        assert jpda.info["marginals"].shape == (n, m + 1) and np.all(jpda.info["marginals"][:, m] == 1)


def test_soft_flag():
    assert make_associator("jpda").soft is True and make_associator("mnn").soft is False


def test_true_mass_on_hand_built_marginals():
    truth = np.array([1, -1, 0])
    one_hot = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], float)
    assert true_mass(one_hot, truth) == 1.0
    beta = np.array([[0.1, 0.7, 0.2], [0.3, 0.3, 0.4], [0.5, 0.0, 0.5]])
    assert true_mass(beta, truth) == pytest.approx((0.7 + 0.4 + 0.5) / 3)
    wrong = np.array([[1, 0, 0], [1, 0, 0], [0, 0, 1]], float)
    assert true_mass(wrong, truth) == 0.0
    assert np.isnan(true_mass(np.zeros((0, 3)), np.zeros(0, int)))
    with pytest.raises(ValueError, match="do not fit"):
        true_mass(beta, np.array([0, 1]))
    with pytest.raises(ValueError, match="outside -1..1"):
        true_mass(beta, np.array([2, 0, 0]))


@pytest.mark.parametrize("param,value,needle", [
    ("p_detect", 0, "params.p_detect must be a finite number in (0, 1], got 0"),
    ("p_detect", 1.5, "params.p_detect must be a finite number in (0, 1], got 1.5"),
    ("confidence", 1.0, "params.confidence"),
    ("clutter_density", 0.0, "params.clutter_density must be a finite number > 0"),
    ("max_events", 0, "params.max_events must be an integer >= 1"),
    ("max_events", 2.5, "params.max_events must be an integer"),
])
def test_bad_parameters_are_one_line_errors(param, value, needle):
    with pytest.raises(UserError) as exc:
        make_associator("jpda", **{param: value})
    assert needle in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("setting,needle", [("params.p_detect=0", "params.p_detect"),
                                            ("params.p_detect=1.5", "(0, 1]")])
def test_bad_parameters_on_the_command_line(capsys, setting, needle):
    code = main(["run", "--method", "jpda", "--set", setting, "--frames", "2"])
    assert_one_line_error(capsys, code, needle)
