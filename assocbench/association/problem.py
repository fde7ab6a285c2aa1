"""``Problem``: one frame's association problem, measurement-model agnostic (dimension ``d``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit, types
from scipy.linalg.lapack import dpotrf

NO_MATCH = -1


SMALL_FACTOR = 40   # P up to this order is factorised by the compiled loop, beyond by LAPACK (faster there)


def _as_float(name: str, value, shape: tuple) -> np.ndarray:
    """``value`` as a C-ordered float64 array: a view where it already is one (no copy; the caller
    must not write it while the problem is in use), else a converted copy."""
    arr = np.ascontiguousarray(_real_numbers(name, value), dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"Problem.{name} has shape {arr.shape}, expected {shape}")
    return arr.view() if arr is value else arr


def _real_numbers(name: str, value) -> np.ndarray:
    """``value`` as a numpy array of real numbers; ``ValueError`` naming the field for text,
    ``None``, objects or complex values (a float cast would drop the imaginary part)."""
    if value is None:       # np.asarray(None) would become NaN, then a shape or NaN message
        raise ValueError(f"Problem.{name} must be an array of real numbers, got None")
    try:
        arr = np.asarray(value)
        if arr.dtype.kind in "biuf":
            return arr
        if arr.dtype.kind in "cUS":
            raise ValueError("complex values" if arr.dtype.kind == "c" else "text")
        return arr.astype(np.float64)       # objects holding numbers are converted; others raise
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Problem.{name} must be an array of real numbers ({exc})") from None


FIELDS_SCREENED = ("zhat", "z", "R", "P")   # _screen's order: its verdict 1..4 names one of them


@njit(cache=True)
def _screen(zhat, z, R, P, small):
    """Every check of the arrays in one compiled pass where it can decide: (verdict, ``max|P|``). 0:
    all finite, ``R`` strictly and ``P`` semidefinitely pass ``_check_spd`` (``P`` up to order
    ``small``); 1..4: the first of ``FIELDS_SCREENED`` not finite; 5 / 6: ``R`` / ``P`` need
    ``_check_spd`` itself; 7: ``P`` above ``small`` needs LAPACK (``_decide_definite``)."""
    for code, arr in ((1, zhat.ravel()), (2, z.ravel()), (3, R.ravel()), (4, P.ravel())):
        for v in arr:
            if not np.isfinite(v):
                return code, 0.0
    if R.shape[0]:
        scale, asymmetry = _scale_and_asymmetry(R)
        if asymmetry > 1e-9 * max(scale, 1e-300) or _first_unfactorised(R, 0.0) >= 0:
            return 5, 0.0
    if P.shape[0]:
        stack = P.reshape((1, P.shape[0], P.shape[1]))
        scale, asymmetry = _scale_and_asymmetry(stack)
        scale = max(scale, 1e-300)
        if asymmetry > 1e-9 * scale:
            return 6, scale
        if P.shape[0] > small:
            return 7, scale
        if _first_unfactorised(stack, 1e-10 * scale) >= 0:
            return 6, scale
    return 0, 0.0


@njit(cache=True)
def _screen_blocks(zhat, z, R, P):
    """Construction's checks of what every associator reads, one compiled pass, O(m d³ + n d³):
    every entry of ``zhat``, ``z``, ``R`` and of ``P``'s (d, d) diagonal blocks finite, each ``R_i``
    symmetric with a Cholesky factor, each ``P_jj`` symmetric (``|A - Aᵀ| <= 1e-9 · s``) with
    ``P_jj + τ·I`` factorisable, ``s`` the blocks' ``max|·|``, ``τ = 1e-10 · s``. Each is necessary
    for the whole ``P`` to pass ``_check_spd`` (a semidefinite ``P`` has ``max|P|`` on its diagonal,
    and a principal block's least eigenvalue is at least ``P``'s). False: the full check decides
    (``_screen``)."""
    (n, d), m = zhat.shape, z.shape[0]
    for j in range(n):
        for a in range(d):
            if not np.isfinite(zhat[j, a]):
                return False
    for i in range(m):
        for a in range(d):
            if not np.isfinite(z[i, a]):
                return False
    L = np.empty((d, d))
    scale, asymmetry = 0.0, 0.0
    for i in range(m):
        scale, asymmetry = _block_scale(R[i], 0, d, scale, asymmetry)
    if not scale == scale or asymmetry > 1e-9 * max(scale, 1e-300):     # NaN scale: a NaN or inf
        return False
    for i in range(m):
        if not _block_factorisable(R[i], 0, d, 0.0, L):
            return False
    scale, asymmetry = 0.0, 0.0
    for j in range(n):
        scale, asymmetry = _block_scale(P, j * d, d, scale, asymmetry)
    if not scale == scale:              # a NaN or infinite entry
        return False
    scale = max(scale, 1e-300)
    if asymmetry > 1e-9 * scale:
        return False
    for j in range(n):
        if not _block_factorisable(P, j * d, d, 1e-10 * scale, L):
            return False
    return True


@njit(inline="always")
def _block_scale(A, o, d, scale, asymmetry):
    """``(max(scale, max|B|), max(asymmetry, max|B - Bᵀ|))`` for ``B = A[o:o+d, o:o+d]``; NaN scale
    for a non-finite entry."""
    for a in range(d):
        v = A[o + a, o + a]
        if not np.isfinite(v):
            return np.nan, asymmetry
        scale = max(scale, abs(v))
        for b in range(a):
            u, w = A[o + a, o + b], A[o + b, o + a]
            if not (np.isfinite(u) and np.isfinite(w)):
                return np.nan, asymmetry
            scale = max(scale, abs(u), abs(w))
            asymmetry = max(asymmetry, abs(u - w))
    return scale, asymmetry


@njit(inline="always")
def _block_factorisable(A, o, d, shift, L):
    """Whether ``B + shift·I`` (lower triangle read) has a Cholesky factor: every pivot ``> 0``; for
    d = 2 the pivots ``a`` and ``c - b·(b/a)`` without a square root."""
    if d == 2:
        a = A[o, o] + shift
        if not a > 0.0:
            return False
        b = A[o + 1, o]
        return (A[o + 1, o + 1] + shift) - b * (b / a) > 0.0
    return _cholesky_pivots_positive(A, o, d, shift, L)


@njit(inline="always")
def _cholesky_pivots_positive(A, o, d, shift, L):
    """Whether the Cholesky factorisation of ``A[o:o+d, o:o+d] + shift·I`` (lower triangle read)
    has every pivot ``> 0``; the factor is built in ``L`` (d, d)."""
    for a in range(d):
        for b in range(a + 1):
            acc = A[o + a, o + b] + (shift if a == b else 0.0)
            for c in range(b):
                acc -= L[a, c] * L[b, c]
            if a == b:
                if not acc > 0.0:
                    return False
                L[a, a] = np.sqrt(acc)
            else:
                L[a, b] = acc / L[b, b]
    return True


@njit(cache=True)
def _c_ordered(shape, strides):
    """numpy's C-contiguity rule for float64 (strides of the later lengths times 8 bytes; empty is
    contiguous)."""
    for length in shape:
        if length == 0:
            return True
    step = 8
    for k in range(len(shape) - 1, -1, -1):
        if shape[k] != 1 and strides[k] != step:
            return False
        step *= shape[k]
    return True


# Any float64 array of these ranks, read-only or not, C-ordered or not: numba converts a C-ordered
# writeable array to it for free (its dispatch is the cheapest type check there is), and the
# layout is checked inside; an array of any other type leaves the fast path (TypeError: slow, but
# such an input is converted anyway).
_ANY_F64 = {rank: types.Array(types.float64, rank, "A", readonly=True) for rank in (2, 3)}


@njit(cache=True)
def _screen_plain(zhat, z, R, P):
    """Construction's fast path: -2 when an array is not C-ordered, -1 when the shapes disagree,
    else ``_screen_blocks``' verdict as 1 or 0."""
    if not (_c_ordered(zhat.shape, zhat.strides) and _c_ordered(z.shape, z.strides)
            and _c_ordered(R.shape, R.strides) and _c_ordered(P.shape, P.strides)):
        return -2
    (n, d), m = zhat.shape, z.shape[0]
    if z.shape[1] != d or R.shape != (m, d, d) or P.shape != (n * d, n * d):
        return -1
    return 1 if _screen_blocks(zhat, z, R, P) else 0


def _screen_plain_first_call(zhat, z, R, P) -> int:
    """``_screen_plain``'s first call: compile or load its one signature, forbid others (another
    type raises TypeError and leaves the fast path), and route later calls to it."""
    global _screen_plain_call
    _screen_plain.compile((_ANY_F64[2], _ANY_F64[2], _ANY_F64[3], _ANY_F64[2]))
    _screen_plain.disable_compile()
    _screen_plain_call = _screen_plain
    return _screen_plain(zhat, z, R, P)


_screen_plain_call = _screen_plain_first_call


def _check_spd(name: str, mats: np.ndarray, allow_semidefinite: bool = False) -> None:
    """Raise if a matrix of the stack is not symmetric (``|A - Aᵀ| <= 1e-9 · max|A|``) positive
    definite (a Cholesky factor exists, as gating needs) or, with ``allow_semidefinite``,
    semidefinite (``λ >= -1e-10 · max|A|``). A singular ``R`` (a "noiseless" sensor) is refused:
    ``S = P_JJ + R`` would be singular wherever ``P`` is. Semidefinite: a Cholesky factorisation of
    ``A + τ·I`` proves ``λ_min(A) > -τ`` (up to its backward error, far inside the tolerance); only
    a failure falls back to the eigenvalues, whose refusals these are."""
    if mats.size == 0:
        return
    stack = mats if mats.ndim == 3 else mats[None]
    scale, asymmetry = _scale_and_asymmetry(stack)
    scale = max(scale, 1e-300)
    if asymmetry > 1e-9 * scale:
        raise ValueError(f"Problem.{name} is not symmetric")
    _decide_definite(name, mats, 1e-10 * scale if allow_semidefinite else 0.0)


def _decide_definite(name: str, mats: np.ndarray, tolerance: float) -> None:
    """``_check_spd``'s verdict on a symmetric stack: Cholesky of each ``A + tolerance·I`` (compiled
    up to ``SMALL_FACTOR``, LAPACK beyond), eigenvalues only where one fails; raises naming the
    matrix."""
    stack = mats if mats.ndim == 3 else mats[None]
    if mats.shape[-1] <= SMALL_FACTOR:
        factorised = _first_unfactorised(stack, tolerance) < 0
    else:
        shifted = mats.copy()
        shifted.flat[::mats.shape[0] + 1] += tolerance
        # shifted.T is Fortran-ordered, so LAPACK factorises it in place, without another copy;
        # its upper triangle is the lower one eigvalsh reads
        factorised = dpotrf(shifted.T, lower=0, clean=0, overwrite_a=1)[1] == 0
    if factorised:
        return
    if tolerance == 0.0:            # definite: no Cholesky factor is the refusal (λ_min <= 0, or so near)
        k = _first_unfactorised(stack, 0.0)
        where = "" if mats.ndim == 2 else f"[{k}]"
        raise ValueError(f"Problem.{name}{where} is not positive definite (singular or indefinite: it has no "
                         "Cholesky factor); give every noise covariance eigenvalues > 0, e.g. sigma**2 * I "
                         "with sigma > 0 for a nearly noiseless sensor")
    bad = np.linalg.eigvalsh(mats).min(axis=-1) < -tolerance
    if np.any(bad):
        where = "" if mats.ndim == 2 else f"[{int(np.flatnonzero(bad)[0])}]"
        raise ValueError(f"Problem.{name}{where} is not positive semidefinite")


@njit(cache=True)
def _scale_and_asymmetry(stack):
    """``max|A|`` and ``max|A - Aᵀ|`` over a stack of square matrices, in one pass."""
    scale, asym = 0.0, 0.0
    for k in range(stack.shape[0]):
        A = stack[k]
        for a in range(A.shape[0]):
            scale = max(scale, abs(A[a, a]))
            for b in range(a):
                scale = max(scale, abs(A[a, b]), abs(A[b, a]))
                asym = max(asym, abs(A[a, b] - A[b, a]))
    return scale, asym


@njit(cache=True)
def _first_unfactorised(stack, shift):
    """Index of the first ``A`` whose ``A + shift·I`` has no Cholesky factor (lower triangle, as
    ``eigvalsh``), or -1."""
    d = stack.shape[1]
    L = np.empty((d, d))
    for k in range(stack.shape[0]):
        if not _cholesky_pivots_positive(stack[k], 0, d, shift, L):
            return k
    return -1


F64 = np.dtype(np.float64)


ND = np.ndarray


def _plain_views(z, R, zhat, P) -> dict | None:
    """Read-only views of the four arrays and ``_screen_blocks``' verdict where each is already a
    C-ordered float64 ``ndarray`` of agreeing shapes (what the harness and simulators pass), by
    identity tests and one compiled call; None otherwise (``_converted`` converts or raises)."""
    if not (type(z) is ND and type(R) is ND and type(zhat) is ND and type(P) is ND
            and z.dtype is F64 and R.dtype is F64 and zhat.dtype is F64 and P.dtype is F64):
        return None
    try:
        verdict = _screen_plain_call(zhat, z, R, P)
    except TypeError:       # a rank _screen_plain has no signature for: the general path names it
        return None
    if verdict < 0:
        return None
    return {"zhat": zhat.view(), "z": z.view(), "R": R.view(), "P": P.view(), "screened": verdict == 1}


def _converted(z, R, zhat, P) -> dict:
    """The four arrays as C-ordered float64 (views or copies) and ``_screen_blocks``' verdict;
    ``ValueError`` naming the first mis-shaped field."""
    zhat, z = (np.asarray(_real_numbers(name, v), dtype=np.float64) for name, v in (("zhat", zhat), ("z", z)))
    for name, arr in (("zhat", zhat), ("z", z)):
        if arr.ndim != 2:
            raise ValueError(f"Problem.{name} must be 2-D (rows, d), got shape {arr.shape}")
    (n, d), m = zhat.shape, z.shape[0]
    arrays = {"zhat": _as_float("zhat", zhat, (n, d)), "z": _as_float("z", z, (m, d)),
              "R": _as_float("R", R, (m, d, d)), "P": _as_float("P", P, (n * d, n * d))}
    arrays["screened"] = _screen_blocks(arrays["zhat"], arrays["z"], arrays["R"], arrays["P"])
    return arrays


def _angular_dims(angular, d: int) -> tuple[int, ...]:
    """``angular`` as a tuple of ints in ``0..d-1``, or raise; cached where hashable."""
    try:
        return _angular_dims_cached(angular, d)
    except TypeError:           # unhashable (a list, an array): checked uncached
        return _angular_dims_checked(angular, d)


@lru_cache(maxsize=256)
def _angular_dims_cached(angular, d: int) -> tuple[int, ...]:
    return _angular_dims_checked(angular, d)


def _angular_dims_checked(angular, d: int) -> tuple[int, ...]:
    ang = tuple(int(a) for a in angular)
    if any(a < 0 or a >= d for a in ang):
        raise ValueError(f"Problem.angular {ang} names dimensions outside 0..{d - 1}")
    return ang


@lru_cache(maxsize=1024)
def _default_ids(n: int) -> np.ndarray:
    """``0..n-1``, read-only, one array per n shared by every problem without map ids."""
    ids = np.arange(n)
    ids.flags.writeable = False
    return ids


@dataclass(frozen=True, eq=False, init=False)     # __init__ below: the fields' checks in one pass
class Problem:
    """Measurements ``z`` (m, d) with noise ``R`` (m, d, d); predictions ``zhat`` (n, d) with joint
    covariance ``P`` (n·d, n·d), cross terms included; ``landmark_ids`` (n,); ``volume`` |Y| of the
    measurement domain; ``angular`` the dims that wrap; optionally ``descriptors`` (m, D) and
    ``landmark_descriptors`` (n, D), both or neither, for appearance methods.

    Pairing landmarks J with features I has innovation covariance ``P[J, J] + blockdiag(R[I])``. Bad
    input is a ``ValueError`` naming the field: construction checks shapes and what every associator
    reads (each ``R_i``, each ``P_jj``), O(m d³ + n d³); the whole ``P``, O((nd)³), is
    ``validate()``'s. The arrays are read-only views of the caller's where already C-ordered
    float64: do not write them while the problem is in use.
    """

    z: np.ndarray
    R: np.ndarray
    zhat: np.ndarray
    P: np.ndarray
    landmark_ids: np.ndarray | None = None
    volume: float = 1.0
    angular: tuple[int, ...] = ()
    descriptors: np.ndarray | None = None
    landmark_descriptors: np.ndarray | None = None

    def __init__(self, z: np.ndarray, R: np.ndarray, zhat: np.ndarray, P: np.ndarray,
                 landmark_ids: np.ndarray | None = None, volume: float = 1.0, angular: tuple[int, ...] = (),
                 descriptors: np.ndarray | None = None, landmark_descriptors: np.ndarray | None = None) -> None:
        arrays = _plain_views(z, R, zhat, P) or _converted(z, R, zhat, P)
        screened = arrays.pop("screened")
        n, d = arrays["zhat"].shape
        if landmark_ids is None:
            ids = _default_ids(n)               # shared and read-only already
        else:
            ids = np.array(landmark_ids)
            if ids.shape != (n,):
                raise ValueError(f"Problem.landmark_ids has shape {ids.shape}, expected {(n,)}")
            ids.setflags(write=False)
        try:
            bad_volume = not math.isfinite(volume) or volume <= 0
        except TypeError:       # text, None, complex: math.isfinite's own message names no field
            bad_volume = True
        if bad_volume:
            raise ValueError(f"Problem.volume must be a positive finite number, got {volume!r}")
        angular = angular if type(angular) is tuple and not angular else _angular_dims(angular, d)
        for arr in arrays.values():
            # one problem is shared by every method of a sweep: none may change it for the next
            arr.setflags(write=False)   # cheaper than .flags.writeable, which builds an object
        if descriptors is None and landmark_descriptors is None:
            appearance = _NO_APPEARANCE
        else:
            appearance = _appearance(descriptors, landmark_descriptors, arrays["z"].shape[0], n)
        # frozen: past __setattr__, in one step (a dataclass __init__ set each field in its own call)
        self.__dict__.update(arrays, landmark_ids=ids, volume=volume, angular=angular, _validated=False, **appearance)
        if not screened:
            self.validate()             # decides now: raises naming the field, or passes

    def validate(self) -> Problem:
        """Check the whole of ``P`` (finite, symmetric, positive semidefinite) and every other field
        once, raising ``ValueError`` naming the field; returns the problem. O((nd)³), at most once
        per problem (copies keep the verdict); the harness calls it before any method runs, and
        every method or score reading ``P``'s cross terms calls it first."""
        if self._validated:
            return self
        verdict, scale = _screen(self.zhat, self.z, self.R, self.P, SMALL_FACTOR)
        if 1 <= verdict <= 4:
            raise ValueError(f"Problem.{FIELDS_SCREENED[verdict - 1]} contains NaN or infinite values")
        if verdict == 5:                # the slow path decides (and names the matrix), or passes
            _check_spd("R", self.R)
        if verdict in (5, 6):
            _check_spd("P", self.P, allow_semidefinite=True)
        if verdict == 7:
            _decide_definite("P", self.P, 1e-10 * scale)
        for name in DESCRIPTOR_FIELDS:
            _check_finite(name, getattr(self, name))
        object.__setattr__(self, "_validated", True)
        return self

    def __eq__(self, other: object) -> bool:
        """Equal when every array is equal, element by element (and the scalars match)."""
        if not isinstance(other, Problem):
            return NotImplemented
        arrays = ("z", "R", "zhat", "P", "landmark_ids")
        return (all(np.array_equal(getattr(self, a), getattr(other, a)) for a in arrays)
                and self.volume == other.volume and self.angular == other.angular
                and all(_same_or_both_none(getattr(self, a), getattr(other, a)) for a in DESCRIPTOR_FIELDS))

    __hash__ = None  # mutable arrays inside: not hashable

    @property
    def m(self) -> int:
        return self.z.shape[0]

    @property
    def n(self) -> int:
        return self.zhat.shape[0]

    @property
    def d(self) -> int:
        return self.zhat.shape[1]

    def block(self, j: int, k: int | None = None) -> np.ndarray:
        """The (d, d) block ``P[j, k]`` of the joint prediction covariance (``k`` defaults to ``j``)."""
        d = self.d
        k = j if k is None else k
        return self.P[j * d:(j + 1) * d, k * d:(k + 1) * d]


DESCRIPTOR_FIELDS = ("descriptors", "landmark_descriptors")
_NO_APPEARANCE = dict.fromkeys(DESCRIPTOR_FIELDS)


def _appearance(descriptors, landmark_descriptors, m: int, n: int) -> dict:
    """The two descriptor arrays, read-only, after the free checks: both given, real, ``(m, D)`` and
    ``(n, D)``. Finiteness is ``validate``'s."""
    if descriptors is None or landmark_descriptors is None:
        given = "descriptors" if landmark_descriptors is None else "landmark_descriptors"
        raise ValueError(f"Problem.{given} needs its partner: give descriptors (m, D) and landmark_descriptors "
                         "(n, D) together, or neither")
    out = {}
    for name, value, rows in (("descriptors", descriptors, m), ("landmark_descriptors", landmark_descriptors, n)):
        arr = np.array(_real_numbers(name, value))      # a copy: no caller's array can change it later
        if arr.ndim != 2 or arr.shape[0] != rows or arr.shape[1] == 0:
            raise ValueError(f"Problem.{name} has shape {arr.shape}, expected ({rows}, D) with D >= 1")
        arr.setflags(write=False)
        out[name] = arr
    if out["descriptors"].shape[1] != out["landmark_descriptors"].shape[1]:
        raise ValueError(f"Problem.descriptors have D = {out['descriptors'].shape[1]}, landmark_descriptors "
                         f"D = {out['landmark_descriptors'].shape[1]}: both must have one length")
    return out


def _check_finite(name: str, arr: np.ndarray | None) -> None:
    """Raise naming the field when a floating descriptor array holds NaN or infinity."""
    if arr is not None and arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise ValueError(f"Problem.{name} contains NaN or infinite values")


def _same_or_both_none(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


def validate_association(association, problem: Problem) -> np.ndarray:
    """The association as an (n,) int array (entry ``j``: the feature paired with candidate ``j``,
    or -1), or ``ValueError`` saying what is wrong.
    """
    a = np.asarray(association)
    if a.shape != (problem.n,):
        raise ValueError(f"association has shape {a.shape}, expected ({problem.n},)")
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or np.any(a != np.round(a)):
            raise ValueError("association entries must be integer feature indices or -1")
    a = a.astype(np.int64)
    if np.any((a < NO_MATCH) | (a >= problem.m)):
        bad = a[(a < NO_MATCH) | (a >= problem.m)][0]
        raise ValueError(f"association pairs a landmark with feature {bad}, outside -1..{problem.m - 1}")
    used = a[a >= 0]
    if len(np.unique(used)) != len(used):
        dup = int(np.flatnonzero(np.bincount(used) > 1)[0])   # the feature index itself
        raise ValueError(f"association uses feature {dup} more than once")
    return a


def pairs_of(association: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(landmark indices, feature indices) of the pairings in an association."""
    j = np.flatnonzero(association >= 0)
    return j, association[j]
