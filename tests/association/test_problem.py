"""Problem and association validation: bad input names the field."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench import Problem, validate_association


def make(**over):
    fields = dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((3, 2)), P=np.eye(6), volume=100.0)
    fields.update(over)
    return Problem(**fields).validate()


@pytest.mark.parametrize("over,field", [
    (dict(P=-np.eye(6)), "Problem.P"),
    (dict(P=np.triu(np.ones((6, 6)))), "Problem.P"),
    (dict(R=np.stack([np.eye(2), -np.eye(2)])), r"Problem.R\[1\]"),
    (dict(z=np.array([[np.nan, 0.0], [0.0, 0.0]])), "Problem.z"),
    (dict(zhat=np.ones((3, 3))), "Problem"),
    (dict(P=np.eye(5)), "Problem.P"),
    (dict(R=np.eye(2)), "Problem.R"),
    (dict(z=np.zeros(4)), "Problem.z"),
    (dict(volume=0.0), "Problem.volume"),
    (dict(angular=(2,)), "Problem.angular"),
    (dict(landmark_ids=np.arange(2)), "Problem.landmark_ids"),
])
def test_bad_problem_raises_value_error_naming_the_field(over, field):
    with pytest.raises(ValueError, match=field):
        make(**over)


def test_empty_problems_are_valid():
    p = Problem(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2)), np.zeros((0, 0)))
    assert (p.m, p.n, p.d) == (0, 0, 2)


@pytest.mark.parametrize("assoc,msg", [
    ([0, 0, -1], "more than once"), ([0, 5, -1], "outside"), ([0, -2, 1], "outside"),
    ([0, 1], "shape"), ([0.5, -1, -1], "integer"),
])
def test_invalid_associations_are_rejected(assoc, msg):
    with pytest.raises(ValueError, match=msg):
        validate_association(np.array(assoc), make())


def test_valid_association_passes():
    assert validate_association([1, -1, 0], make()).tolist() == [1, -1, 0]


def _eigen_rule(mats, semidefinite):
    """The eigenvalue test the Cholesky path must agree with: every ``λ >= 0`` (semidefinite:
    ``λ >= -1e-10 · max|A|``)."""
    tol = 1e-10 * np.abs(mats).max() if semidefinite else 0.0
    return bool(np.all(np.linalg.eigvalsh(mats).min(axis=-1) >= -tol))


def _with_smallest_eigenvalue(rng, dim, smallest):
    """A random symmetric matrix with eigenvalues ``smallest`` and others in [0.1, 10]."""
    Q, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    lam = np.concatenate([[smallest], rng.uniform(0.1, 10.0, dim - 1)])
    A = (Q * lam) @ Q.T
    return 0.5 * (A + A.T)


def _accepted(field, value, message):
    try:
        make(**{field: value})
    except ValueError as err:
        assert message in str(err)
        return False
    return True


def test_singular_but_semidefinite_P_is_accepted():
    """A P of rank 2 (every landmark a copy of one, as after a perfectly correlated pose error)
    has eigenvalues 0 up to rounding; it must be accepted, and a shifted copy refused."""
    block = np.array([[2.0, 0.5], [0.5, 1.0]])
    P = np.kron(np.ones((3, 3)), block)
    assert make(P=P).P.shape == (6, 6)
    with pytest.raises(ValueError, match="Problem.P is not positive semidefinite"):
        make(P=P - 1e-6 * np.eye(6))


@pytest.mark.parametrize("smallest", [1e-3, 1e-14, 0.0, -1e-14, -1e-11, -1e-9, -1e-3, -1.0])
def test_cholesky_validation_agrees_with_the_eigenvalue_test(rng, smallest):
    """Random symmetric P and R with smallest eigenvalue positive, zero, just inside the
    semidefinite tolerance and outside it: accepted exactly when the eigenvalue rule says. (R is
    tested strictly definite, so within rounding of λ = 0 either verdict is rounding: skipped.)"""
    for _ in range(40):
        P = _with_smallest_eigenvalue(rng, 6, smallest)
        assert _accepted("P", P, "Problem.P is not positive semidefinite") == _eigen_rule(P, True)
        if abs(smallest) < 1e-12:
            continue
        R = np.stack([np.eye(2), _with_smallest_eigenvalue(rng, 2, smallest)])
        assert _accepted("R", R, "Problem.R[1] is not positive definite") == _eigen_rule(R, False)


@pytest.mark.parametrize("field", ["zhat", "z", "R", "P"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("n", [3, 30])          # P of order 6 (compiled Cholesky) and 60 (LAPACK)
def test_the_one_pass_screen_names_a_non_finite_field(field, bad, n):
    """``_screen`` checks every entry in one compiled pass; the error names the field."""
    fields = dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((n, 2)), P=np.eye(2 * n))
    value = fields[field].copy()
    value.flat[-1] = bad
    fields[field] = value
    with pytest.raises(ValueError, match=f"Problem.{field} contains NaN or infinite values"):
        Problem(**fields).validate()


def test_an_asymmetric_R_is_named():
    R = np.stack([np.eye(2), np.array([[1.0, 0.2], [0.0, 1.0]])])
    with pytest.raises(ValueError, match="Problem.R is not symmetric"):
        make(R=R)


@pytest.mark.parametrize("n", [3, 30])          # P of order 6 (compiled Cholesky) and 60 (LAPACK)
def test_the_same_refusals_of_P_at_either_size(n):
    fields = dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((n, 2)))
    asymmetric = np.eye(2 * n)
    asymmetric[0, 1] = 0.5
    with pytest.raises(ValueError, match="Problem.P is not symmetric"):
        Problem(P=asymmetric, **fields).validate()
    with pytest.raises(ValueError, match="Problem.P is not positive semidefinite"):
        Problem(P=np.diag(np.r_[-1.0, np.ones(2 * n - 1)]), **fields).validate()
    singular = np.kron(np.ones((n, n)), np.array([[2.0, 0.5], [0.5, 1.0]]))
    assert Problem(P=singular, **fields).validate().P.shape == (2 * n, 2 * n)


def _cross_terms_only_bad(n, bad):
    """Fields whose P has sound diagonal blocks but is wrong as a whole: ``bad`` "definite" (the
    rank-2 P of ``test_singular_but_semidefinite_P_is_accepted`` shifted below zero), "nan" (one
    off-diagonal entry), "asymmetric" (one cross term)."""
    P = np.kron(np.ones((n, n)), np.array([[2.0, 0.5], [0.5, 1.0]]))
    if bad == "definite":
        P -= 1e-6 * np.eye(2 * n)
    elif bad == "nan":
        P[0, 2] = np.nan
    else:
        P[0, 2] += 0.5
    return dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((n, 2)), P=P)


@pytest.mark.parametrize("n", [3, 30])
@pytest.mark.parametrize("bad,message", [("definite", "Problem.P is not positive semidefinite"),
                                         ("nan", "Problem.P contains NaN or infinite values"),
                                         ("asymmetric", "Problem.P is not symmetric")])
def test_the_whole_of_P_is_checked_by_validate_before_any_cross_term_is_read(n, bad, message):
    """Construction checks what every method reads (each diagonal block of P, O(n d³)); the
    whole P (O((nd)³)) is ``validate``'s, which JCBB, the scorer's joint test and the harness call
    first: the same refusal, before any answer reads a cross term."""
    from assocbench import make_associator
    from assocbench.association.compatibility import jointly_compatible

    problem = Problem(**_cross_terms_only_bad(n, bad))       # its blocks pass: accepted for now
    assert make_associator("mnn").associate(problem).shape == (n,)
    for use in (problem.validate, lambda: make_associator("jcbb").associate(problem),
                lambda: jointly_compatible(problem, np.full(n, -1))):
        with pytest.raises(ValueError, match=message):
            use()


def test_a_problem_checked_whole_keeps_the_verdict_in_its_copies():
    import copy

    fields = _cross_terms_only_bad(3, "definite")
    fields["P"] = np.kron(np.ones((3, 3)), np.array([[2.0, 0.5], [0.5, 1.0]]))
    problem = Problem(**fields)
    assert not problem._validated
    assert problem.validate() is problem and problem._validated
    assert copy.copy(problem)._validated


def test_plain_arrays_are_kept_as_views_and_any_other_input_is_converted_to_the_same_problem():
    """Construction's fast path (C-ordered float64 arrays of agreeing shapes: read-only views,
    no copy, the caller's arrays left writeable) and its general path (lists, Fortran order,
    an angular list of numpy integers: converted) build the same problem; a shape that does not
    agree leaves the fast path and is refused naming the field."""
    from assocbench.models.synthetic import range_bearing_problem

    p, _ = range_bearing_problem(np.random.default_rng(3), n=6)
    z, R, zhat, P = (np.array(a) for a in (p.z, p.R, p.zhat, p.P))
    plain = Problem(z, R, zhat, P, volume=p.volume, angular=(1,))
    for mine, theirs in ((plain.z, z), (plain.R, R), (plain.zhat, zhat), (plain.P, P)):
        assert np.shares_memory(mine, theirs) and theirs.flags.writeable and not mine.flags.writeable
    other = Problem(z.tolist(), np.asfortranarray(R), zhat.tolist(), np.asfortranarray(P), volume=p.volume,
                    angular=[np.int64(1)])
    assert other == plain and other.angular == (1,) and type(other.angular[0]) is int
    assert not np.shares_memory(other.P, P) and not other.P.flags.writeable
    with pytest.raises(ValueError, match=r"Problem.P has shape \(11, 11\)"):
        Problem(z, R, zhat, P[:11, :11].copy())
    for _ in range(2):          # a refused angular is refused again (no verdict cached)
        with pytest.raises(ValueError, match="Problem.angular"):
            Problem(z, R, zhat, P, angular=(2,))
