"""``Problem``: one frame's association problem, measurement-model agnostic (dimension ``d``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NO_MATCH = -1


def _as_float(name: str, value, shape: tuple) -> np.ndarray:
    arr = np.array(value, dtype=np.float64)  # a copy: the caller's arrays stay writeable
    if arr.shape != shape:
        raise ValueError(f"Problem.{name} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"Problem.{name} contains NaN or infinite values")
    return arr


def _check_spd(name: str, mats: np.ndarray, allow_semidefinite: bool = False) -> None:
    """Raise if any matrix of the stack is not symmetric positive (semi)definite."""
    if mats.size == 0:
        return
    scale = max(np.abs(mats).max(), 1e-300)
    if np.abs(mats - np.swapaxes(mats, -1, -2)).max() > 1e-9 * scale:
        raise ValueError(f"Problem.{name} is not symmetric")
    eig = np.linalg.eigvalsh(mats)
    bad = eig.min(axis=-1) < (-1e-10 * scale if allow_semidefinite else 0.0)
    if np.any(bad):
        where = "" if mats.ndim == 2 else f"[{int(np.flatnonzero(bad)[0])}]"
        raise ValueError(f"Problem.{name}{where} is not positive {'semi' if allow_semidefinite else ''}definite")


@dataclass(frozen=True, eq=False)
class Problem:
    """Measurements ``z`` (m, d) with noise ``R`` (m, d, d); predictions ``zhat`` (n, d) with
    joint covariance ``P`` (n·d, n·d) including cross terms; ``landmark_ids`` (n,) map ids;
    ``volume`` the measure |Y| of the measurement domain; ``angular`` the dims that wrap.

    The innovation covariance of pairing landmarks J with features I is
    ``P[J, J] + blockdiag(R[I])``. Arrays are validated (shape, finiteness, symmetry,
    definiteness) on construction; errors are ``ValueError`` naming the field. The arrays are
    copies and read-only, so an associator cannot change a problem another method will see.
    """

    z: np.ndarray
    R: np.ndarray
    zhat: np.ndarray
    P: np.ndarray
    landmark_ids: np.ndarray | None = None
    volume: float = 1.0
    angular: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731  (frozen dataclass)
        zhat, z = np.asarray(self.zhat, dtype=np.float64), np.asarray(self.z, dtype=np.float64)
        for name, arr in (("zhat", zhat), ("z", z)):
            if arr.ndim != 2:
                raise ValueError(f"Problem.{name} must be 2-D (rows, d), got shape {arr.shape}")
        (n, d), m = zhat.shape, z.shape[0]
        set_("zhat", _as_float("zhat", zhat, (n, d)))
        set_("z", _as_float("z", z, (m, d)))
        set_("R", _as_float("R", self.R, (m, d, d)))
        set_("P", _as_float("P", self.P, (n * d, n * d)))
        ids = np.arange(n) if self.landmark_ids is None else np.array(self.landmark_ids)
        if ids.shape != (n,):
            raise ValueError(f"Problem.landmark_ids has shape {ids.shape}, expected {(n,)}")
        set_("landmark_ids", ids)
        if not np.isfinite(self.volume) or self.volume <= 0:
            raise ValueError(f"Problem.volume must be a positive finite number, got {self.volume!r}")
        ang = tuple(int(a) for a in self.angular)
        if any(a < 0 or a >= d for a in ang):
            raise ValueError(f"Problem.angular {ang} names dimensions outside 0..{d - 1}")
        set_("angular", ang)
        _check_spd("R", self.R)
        _check_spd("P", self.P, allow_semidefinite=True)
        for name in ("z", "R", "zhat", "P", "landmark_ids"):
            # one problem is shared by every method of a sweep: none may change it for the next
            getattr(self, name).flags.writeable = False

    def __eq__(self, other: object) -> bool:
        """Equal when every array is equal, element by element (and the scalars match)."""
        if not isinstance(other, Problem):
            return NotImplemented
        arrays = ("z", "R", "zhat", "P", "landmark_ids")
        return (all(np.array_equal(getattr(self, a), getattr(other, a)) for a in arrays)
                and self.volume == other.volume and self.angular == other.angular)

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


def validate_association(association, problem: Problem) -> np.ndarray:
    """Return the association as an (n,) int array, or raise ``ValueError`` saying what is wrong.

    Entry ``j`` is the index of the feature paired with candidate ``j``, or -1.
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
