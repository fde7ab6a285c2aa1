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
    (dict(R=np.zeros((2, 2, 2))), r"Problem.R\[0\] is not positive definite"),   # a "noiseless" sensor: S = P_JJ
    (dict(R=np.stack([np.eye(2), np.ones((2, 2))])), r"Problem.R\[1\] is not positive definite"),   # rank 1
    (dict(z=np.array([[np.nan, 0.0], [0.0, 0.0]])), "Problem.z"),
    (dict(zhat=np.ones((3, 3))), "Problem"),
    (dict(P=np.eye(5)), "Problem.P"),
    (dict(R=np.eye(2)), "Problem.R"),
    (dict(z=np.zeros(4)), "Problem.z"),
    (dict(volume=0.0), "Problem.volume"),
    (dict(volume="100"), "Problem.volume"),     # was math.isfinite's TypeError, naming no field
    (dict(volume=None), "Problem.volume"),
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
    """The eigenvalue test the Cholesky path must agree with: every ``λ > 0`` (semidefinite:
    ``λ >= -1e-10 · max|A|``)."""
    smallest = np.linalg.eigvalsh(mats).min(axis=-1)
    return bool(np.all(smallest >= -1e-10 * np.abs(mats).max())) if semidefinite else bool(np.all(smallest > 0))


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
    semidefinite tolerance and outside it: accepted exactly when the eigenvalue rule says. (R must
    be strictly definite, so within rounding of λ = 0 either verdict is rounding: skipped.)"""
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


def test_the_compiled_layout_check_is_numpys_c_contiguity():
    """``_c_ordered`` (the fast path's layout test, compiled) agrees with numpy's
    ``flags.c_contiguous`` on slices, transposes, axes of length 1 and empty arrays."""
    from assocbench.association.problem import _c_ordered

    base = np.arange(120.0).reshape(4, 5, 6)
    cases = [base, base[1:3], base[:, 1:3], base[:, :, ::2], base.transpose(1, 0, 2), base[:1, :, :],
             base[:, :1, :1], base[:0], base[:, ::-1], base[2], base[2].T, base[2, :1], base[2, :, :1],
             base[2, 1:2, ::3], np.empty((0, 2)), np.empty((3, 0))[::2], np.ones((1, 1))[:, ::-1]]
    for arr in cases:
        assert _c_ordered(arr.shape, arr.strides) == arr.flags.c_contiguous, (arr.shape, arr.strides)


class _Subclass(np.ndarray):
    """An ndarray subclass: the fast path keeps exact ndarrays only (a view of a subclass would
    carry the subclass's behaviour into the problem)."""


def test_the_fast_path_takes_any_c_ordered_float64_and_leaves_everything_else_to_the_general_one():
    """Read-only C-ordered arrays (another problem's) stay views; Fortran order, a strided view,
    float32, a wrong rank and a subclass take the general path, which converts to the same
    problem or refuses naming the field, as before the compiled fast path."""
    from assocbench.association.problem import _plain_views
    from assocbench.models.synthetic import range_bearing_problem

    p, _ = range_bearing_problem(np.random.default_rng(4), n=5)
    kw = {"landmark_ids": p.landmark_ids, "volume": p.volume, "angular": p.angular}
    again = Problem(p.z, p.R, p.zhat, p.P, **kw)
    assert again == p and all(np.shares_memory(getattr(again, f), getattr(p, f)) for f in ("z", "R", "zhat", "P"))
    z, R, zhat, P = (np.array(a) for a in (p.z, p.R, p.zhat, p.P))
    wide = np.zeros((z.shape[0], 4))
    wide[:, ::2] = z
    others = [(z, R, zhat, np.asfortranarray(P)), (wide[:, ::2], R, zhat, P), (z, R, zhat.view(_Subclass), P)]
    for args in others:
        assert _plain_views(*args) is None
        assert Problem(*args, **kw) == p
    single = zhat.astype(np.float32)
    assert _plain_views(z, R, single, P) is None
    assert Problem(z, R, single, P, **kw) == Problem(z, R, single.astype(np.float64), P, **kw)
    with pytest.raises(ValueError, match=r"Problem.z must be 2-D"):
        Problem(z.ravel(), R, zhat, P)
    with pytest.raises(ValueError, match=r"Problem.R has shape"):
        Problem(z, R[:, :1, :].copy(), zhat, P)
    bad = P.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="Problem.P contains NaN"):
        Problem(z, R, zhat, bad)


@pytest.mark.parametrize("d", [2, 3])
def test_the_screens_block_test_is_the_cholesky_pivot_test(rng, d):
    """``_screen_blocks`` decides each block by its pivots (for d = 2 in closed form, no square
    root): on blocks whose least eigenvalue is just above or below zero (±1e-9 of the scale:
    clear of rounding) it says what the Cholesky factorisation (``_first_unfactorised``) says."""
    from assocbench.association.problem import _first_unfactorised, _screen_blocks

    for smallest in (1e-9, -1e-9, 1e-3, -1e-3):
        for _ in range(50):
            block = _with_smallest_eigenvalue(rng, d, smallest)
            R = block[None].copy()
            expected = _first_unfactorised(R, 0.0) < 0
            assert _screen_blocks(np.zeros((0, d)), np.zeros((1, d)), R, np.zeros((0, 0))) == expected
            assert expected == (smallest > 0)


@pytest.mark.parametrize("field", ["z", "R", "zhat", "P"])
@pytest.mark.parametrize("kind", ["text", "complex", "None"])
def test_an_array_of_no_real_numbers_is_refused_naming_the_field(field, kind):
    """Text and complex values are refused in one line naming the field (complex values were
    cast to float64 with only a warning, their imaginary part dropped); integers and objects
    holding numbers are converted."""
    fields = dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((3, 2)), P=np.eye(6))
    good = Problem(**{**fields, field: fields[field].astype(int).astype(object)})
    assert good == Problem(**{**fields, field: fields[field].astype(int)})
    bad = {"text": fields[field].astype(str), "complex": fields[field] * (1 + 1j), "None": None}[kind]
    with pytest.raises(ValueError, match=rf"^Problem\.{field} must be an array of real numbers"):
        Problem(**{**fields, field: bad})


# ---------------------------------------------------------------- appearance (optional descriptors)

def with_descriptors(m: int = 2, n: int = 3, **over) -> Problem:
    fields = dict(descriptors=np.arange(m * 4, dtype=np.uint8).reshape(m, 4),
                  landmark_descriptors=np.ones((n, 4), np.float32))
    return make(**(fields | over))


def test_descriptors_are_optional_and_kept_read_only_in_their_own_dtype():
    plain = make()
    assert plain.descriptors is None and plain.landmark_descriptors is None
    p = with_descriptors()
    assert p.descriptors.dtype == np.uint8 and p.landmark_descriptors.dtype == np.float32
    assert p.descriptors.shape == (2, 4) and p.landmark_descriptors.shape == (3, 4)
    assert not p.descriptors.flags.writeable and not p.landmark_descriptors.flags.writeable
    assert p == with_descriptors() and p != plain and p != with_descriptors(landmark_descriptors=np.zeros((3, 4)))


def test_descriptors_are_a_copy_the_caller_cannot_change():
    mine = np.zeros((2, 4))
    p = with_descriptors(descriptors=mine)
    mine[0, 0] = 7.0
    assert p.descriptors[0, 0] == 0.0


@pytest.mark.parametrize("over,message", [
    (dict(landmark_descriptors=None), "Problem.descriptors needs its partner"),
    (dict(descriptors=None), "Problem.landmark_descriptors needs its partner"),
    (dict(descriptors=np.zeros((3, 4))), r"Problem.descriptors has shape \(3, 4\), expected \(2, D\)"),
    (dict(landmark_descriptors=np.zeros(12)), r"Problem.landmark_descriptors has shape \(12,\)"),
    (dict(descriptors=np.zeros((2, 0)), landmark_descriptors=np.zeros((3, 0))), "D >= 1"),
    (dict(landmark_descriptors=np.zeros((3, 5))), "both must have one length"),
    (dict(descriptors=np.array([["a"] * 4] * 2)), "Problem.descriptors must be an array of real numbers"),
    (dict(landmark_descriptors=np.full((3, 4), np.nan)), "Problem.landmark_descriptors contains NaN"),
    (dict(descriptors=np.full((2, 4), np.inf)), "Problem.descriptors contains NaN or infinite"),
])
def test_bad_descriptors_are_refused_naming_the_field(over, message):
    with pytest.raises(ValueError, match=message):
        with_descriptors(**over)


def test_non_finite_descriptors_are_found_by_validate_not_construction():
    """Finiteness costs O(m D): ``validate`` decides it, once, as it does the whole of ``P``."""
    p = Problem(np.zeros((2, 2)), np.repeat(np.eye(2)[None], 2, 0), np.ones((3, 2)), np.eye(6),
                descriptors=np.full((2, 4), np.nan), landmark_descriptors=np.zeros((3, 4)))
    with pytest.raises(ValueError, match="Problem.descriptors contains NaN"):
        p.validate()


def test_the_harness_private_copy_gives_descriptors_of_their_own():
    from assocbench.harness.runner import private_copy

    p = with_descriptors()
    copy = private_copy(p)
    assert copy == p and not np.shares_memory(copy.descriptors, p.descriptors)
    assert not np.shares_memory(copy.landmark_descriptors, p.landmark_descriptors)
    assert not copy.descriptors.flags.writeable and private_copy(make()).descriptors is None
