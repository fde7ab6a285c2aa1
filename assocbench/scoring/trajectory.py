"""Trajectory accuracy and filter consistency of an estimated path, and TUM files. A pose is ``R``
(sensor-to-world) and ``p``; the filter's error convention is

    R_true = R_est · Exp(δθ)   (δθ a body-frame rotation vector),   δp = p_true − p_est (world),

with the pose covariance ``P`` over ``e = [δp, δθ]``. Accuracy: ATE with NO alignment and the RMSE
of ``R_trueᵀ R_est``'s angle (``evo_ape`` without ``-a``, and ``-r angle_deg``). Consistency: NEES_k
= e_kᵀ P_k⁻¹ e_k, whose mean lies in the χ²_{6N} band over N for a consistent filter
(``anees_band``); ``divergence_frame`` finds where it leaves the single-frame bound for good. A NaN
frame makes the result NaN unless excluded by index (``anees(nees, exclude=[0])``: slam's first
frame).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.linalg import LinAlgError, cholesky, solve_triangular
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from ..atomic import OUTPUT_FILE, Role, write_text
from ..errors import UserError

POSE_DOF = 6      # a 3-D pose error [δp, δθ]
PLANE_DOF = 3     # a pose in the plane [δx, δy, δθ]
_ROTATION_TOL = 1e-6      # ‖RᵀR − I‖_max and |det R − 1| accepted as a rotation in a TUM file
_SYMMETRY_TOL = 1e-6      # relative asymmetry of a covariance accepted as rounding


# ---- accuracy ------------------------------------------------------------------------------

def position_errors(p_true: np.ndarray, p_est: np.ndarray) -> np.ndarray:
    """Per-frame position error ``‖p_true,k − p_est,k‖`` (N,), NaN where either is NaN."""
    p_true, p_est = _positions(p_true, "p_true"), _positions(p_est, "p_est")
    _same_length(p_true, p_est, "p_true", "p_est")
    return np.linalg.norm(p_true - p_est, axis=1)


def ate_rmse(p_true: np.ndarray, p_est: np.ndarray) -> float:
    """Absolute trajectory error, no alignment (``evo_ape``'s ``rmse`` without ``-a``/``-s``):

        ATE = sqrt( (1/N) Σ_k ‖p_true,k − p_est,k‖² ),

    NaN if any frame is NaN or there is none."""
    return _rms(position_errors(p_true, p_est))


def rotation_errors_deg(R_true: np.ndarray, R_est: np.ndarray) -> np.ndarray:
    """Per-frame rotation error (deg), the angle of ``M = R_trueᵀ R_est``:

        θ = atan2( ‖vee(M − Mᵀ)‖ / 2, (tr M − 1) / 2 ),

    ``arccos((tr M − 1)/2)`` but accurate near 0 and π. NaN where either is NaN."""
    R_true, R_est = _rotations(R_true, "R_true"), _rotations(R_est, "R_est")
    _same_length(R_true, R_est, "R_true", "R_est")
    M = np.einsum("kji,kjl->kil", R_true, R_est)          # R_trueᵀ R_est per frame
    skew = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1)
    sin = np.linalg.norm(skew, axis=1) / 2
    cos = (np.trace(M, axis1=1, axis2=2) - 1) / 2
    return np.degrees(np.arctan2(sin, cos))


def rotation_rmse_deg(R_true: np.ndarray, R_est: np.ndarray) -> float:
    """``sqrt((1/N) Σ_k θ_k²)`` in degrees (``evo_ape -r angle_deg``'s ``rmse``); NaN if any frame
    is NaN or there is none."""
    return _rms(rotation_errors_deg(R_true, R_est))


def _rms(errors: np.ndarray) -> float:
    return float(np.sqrt(np.mean(errors ** 2))) if errors.size else float("nan")


# ---- consistency ---------------------------------------------------------------------------

def pose_error(R_true: np.ndarray, p_true: np.ndarray, R_est: np.ndarray, p_est: np.ndarray) -> np.ndarray:
    """The filter-convention error ``e = [δp, δθ]`` of one pose:

        δp = p_true − p_est,   δθ = Log(R_estᵀ R_true)   (so that R_true = R_est · Exp(δθ)).

    All NaN when any input is."""
    R_true, R_est = (_rotations(np.asarray(R, dtype=np.float64)[None], name)[0]
                     for R, name in ((R_true, "R_true"), (R_est, "R_est")))
    p_true, p_est = (_positions(np.asarray(p, dtype=np.float64)[None], name)[0]
                     for p, name in ((p_true, "p_true"), (p_est, "p_est")))
    if not all(np.isfinite(x).all() for x in (R_true, p_true, R_est, p_est)):
        return np.full(POSE_DOF, np.nan)
    dtheta = Rotation.from_matrix(R_est.T @ R_true).as_rotvec()
    return np.concatenate([p_true - p_est, dtheta])


def pose_nees(error6: np.ndarray, cov6: np.ndarray) -> float:
    """NEES of one pose through ``P = L Lᵀ``:

        NEES = eᵀ P⁻¹ e = ‖L⁻¹ e‖²,

    χ²_q for a consistent filter (q = 6 in space, 3 in the plane). NaN for a NaN or a ``P`` not
    numerically positive definite (a pivot ``L_ii ≤ sqrt(ε · max|P|)``: slam's first frame).
    ``UserError`` for wrong shapes or an asymmetric ``P``."""
    e = np.asarray(error6, dtype=np.float64)
    P = np.asarray(cov6, dtype=np.float64)
    if e.shape not in ((POSE_DOF,), (PLANE_DOF,)) or P.shape != (len(e), len(e)):
        raise UserError(f"pose NEES needs an error of shape (6,) and a covariance of shape (6, 6) (in the plane: (3,) "
                        f"and (3, 3)), got {e.shape} and {P.shape}")
    if not (np.isfinite(e).all() and np.isfinite(P).all()):
        return float("nan")
    scale = np.abs(P).max()
    if np.abs(P - P.T).max() > _SYMMETRY_TOL * scale:
        raise UserError("pose covariance is not symmetric; pass the filter's covariance P, not a factor of it")
    try:
        L = cholesky(P, lower=True)
    except LinAlgError:
        return float("nan")
    # cholesky only fails on a non-positive pivot; a tiny one would turn rounding into a huge NEES
    if np.min(np.diag(L)) <= np.sqrt(np.finfo(float).eps * scale):
        return float("nan")
    whitened = solve_triangular(L, e, lower=True)
    return float(whitened @ whitened)


def anees(nees: Sequence[float] | np.ndarray, exclude: Sequence[int] = ()) -> float:
    """Average NEES over the frames not excluded:

        ANEES = (1/N) Σ_{k ∉ exclude} NEES_k,   N = number of frames kept.

    ``exclude``: frames left out on purpose (slam's frame 0). Any other NaN makes it NaN, never
    silently dropped; NaN with no frame. Compare with ``anees_band(N)``."""
    values = np.asarray(nees, dtype=np.float64)
    if values.ndim != 1:
        raise UserError(f"NEES must be one value per frame (a 1-D sequence), got shape {values.shape}")
    keep = np.ones(len(values), dtype=bool)
    drop = np.asarray(exclude).reshape(-1)
    if drop.size and not np.issubdtype(drop.dtype, np.integer):
        raise UserError(f"exclude must list frame indices (integers), got {drop.dtype} values")
    drop = drop.astype(np.int64)
    if drop.size and (drop.min() < 0 or drop.max() >= len(values)):
        raise UserError(f"excluded frames {drop.tolist()} are outside 0..{len(values) - 1}; "
                        "exclude frames by their index in the NEES sequence")
    keep[drop] = False
    return float(values[keep].mean()) if keep.any() else float("nan")


def anees_band(frames: int, dof: int = POSE_DOF, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided ``confidence`` band of a consistent filter's ANEES over ``frames`` frames:

        N·ANEES ~ χ²_{dof·N}   ⇒   band = ( χ²_{dof·N}(α/2) / N,  χ²_{dof·N}(1 − α/2) / N ),

    α = 1 − confidence. Below: pessimistic; above: overconfident."""
    _check_count(frames, "frames")
    _check_count(dof, "dof")
    _check_confidence(confidence)
    alpha = 1.0 - confidence
    lo, hi = chi2.ppf([alpha / 2, 1 - alpha / 2], dof * frames)
    return float(lo / frames), float(hi / frames)


def divergence_frame(nees: Sequence[float] | np.ndarray, dof: int = POSE_DOF,
                     confidence: float = 0.999, run: int = 5) -> int:
    """First frame from which the NEES stays above ``χ²_dof(confidence)`` for ``run`` frames,

        k = min { k : NEES_i > χ²_dof(confidence) for all i in k … k + run − 1 },

    or -1. A NaN breaks a run; an excursion cut short by the sequence's end is no divergence."""
    values = np.asarray(nees, dtype=np.float64)
    if values.ndim != 1:
        raise UserError(f"NEES must be one value per frame (a 1-D sequence), got shape {values.shape}")
    _check_count(dof, "dof")
    _check_count(run, "run")
    _check_confidence(confidence)
    above = values > chi2.ppf(confidence, dof)           # NaN compares False
    if len(above) < run:
        return -1
    streak = np.convolve(above.astype(np.int64), np.ones(run, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(streak == run)
    return int(hits[0]) if hits.size else -1


def _check_count(value: int, name: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise UserError(f"{name} must be a whole number of at least 1, got {value!r}")


def _check_confidence(confidence: float) -> None:
    if not 0.0 < confidence < 1.0:
        raise UserError(f"confidence must lie strictly between 0 and 1, got {confidence!r}")


# ---- TUM files -----------------------------------------------------------------------------

def tum_text(stamps: np.ndarray, R: np.ndarray, p: np.ndarray, path: Path | str = "trajectory") -> str:
    """A trajectory as TUM text, one line per pose, ``t tx ty tz qx qy qz qw`` (``R``
    sensor-to-world, scalar last), numbers in shortest round-trip form. ``UserError`` (naming
    ``path``) for mismatched shapes, non-finite values, stamps not increasing, or an ``R`` not a
    rotation."""
    stamps = np.asarray(stamps, dtype=np.float64)
    R, p = _rotations(R, "R"), _positions(p, "p")
    if stamps.shape != (len(R),) or len(p) != len(R):
        raise UserError(f"TUM file {path}: stamps {stamps.shape}, R {R.shape} and p {p.shape} "
                        "must describe the same N poses: (N,), (N, 3, 3), (N, 3)")
    for name, values in (("stamps", stamps), ("R", R), ("p", p)):
        if not np.isfinite(values).all():
            bad = int(np.flatnonzero(~np.isfinite(values.reshape(len(values), -1)).all(axis=1))[0])
            raise UserError(f"TUM file {path}: {name} of pose {bad} is not finite; write only finite poses")
    if np.any(np.diff(stamps) <= 0):
        raise UserError(f"TUM file {path}: stamps must strictly increase (pose "
                        f"{int(np.flatnonzero(np.diff(stamps) <= 0)[0]) + 1} does not)")
    _check_rotations(R, path)
    rows = np.column_stack([stamps, p, Rotation.from_matrix(R).as_quat()])   # quat is (x, y, z, w)
    return "# timestamp tx ty tz qx qy qz qw\n" + "".join(" ".join(repr(float(x)) for x in row) + "\n" for row in rows)


def write_tum(path: Path | str, stamps: np.ndarray, R: np.ndarray, p: np.ndarray,
              role: Role = OUTPUT_FILE) -> None:
    """Write ``tum_text(stamps, R, p)`` to ``path`` atomically."""
    write_text(Path(path), tum_text(stamps, R, p, path), role)


def read_tum(path: Path | str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a TUM file (``#`` comments) into ``(stamps, R, p)``, quaternions normalised;
    ``UserError`` for a missing file or a line that is not 8 numbers with a non-zero quaternion."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise UserError(f"cannot read TUM file {path}: {exc.strerror or type(exc).__name__}; "
                        "check the path") from None
    rows = []
    for number, line in enumerate(lines, start=1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        try:
            row = [float(x) for x in fields]
        except ValueError:
            row = []
        if len(row) != 8 or not np.isfinite(row).all() or not np.any(row[4:]):
            raise UserError(f"TUM file {path} line {number}: expected 8 finite numbers "
                            "'t tx ty tz qx qy qz qw' with a non-zero quaternion")
        rows.append(row)
    data = np.array(rows, dtype=np.float64).reshape(-1, 8)
    R = Rotation.from_quat(data[:, 4:]).as_matrix() if len(data) else np.zeros((0, 3, 3))
    return data[:, 0].copy(), R.reshape(-1, 3, 3), data[:, 1:4].copy()


# ---- input checks --------------------------------------------------------------------------

def _positions(p: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise UserError(f"{name} must be positions of shape (N, 3), got {p.shape}")
    return p


def _rotations(R: np.ndarray, name: str) -> np.ndarray:
    R = np.asarray(R, dtype=np.float64)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise UserError(f"{name} must be rotations of shape (N, 3, 3), got {R.shape}")
    return R


def _same_length(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> None:
    if len(a) != len(b):
        raise UserError(f"{name_a} has {len(a)} poses but {name_b} has {len(b)}; pass the same frames")


def _check_rotations(R: np.ndarray, path: Path | str) -> None:
    """Reject non-rotations: a quaternion would silently replace them by the nearest rotation."""
    gram = np.einsum("kji,kjl->kil", R, R) - np.eye(3)
    bad = (np.abs(gram).max(axis=(1, 2)) > _ROTATION_TOL) | (np.abs(np.linalg.det(R) - 1) > _ROTATION_TOL)
    if bad.any():
        raise UserError(f"TUM file {path}: R of pose {int(np.flatnonzero(bad)[0])} is not a rotation "
                        "(RᵀR ≠ I or det R ≠ 1); pass sensor-to-world rotation matrices")


def pose_columns(prefix: str, R: np.ndarray, p: np.ndarray) -> dict[str, float]:
    """``{prefix}x … {prefix}qw``: a pose as TUM's position and scalar-last quaternion."""
    q = Rotation.from_matrix(R).as_quat()
    return {f"{prefix}{k}": float(v) for k, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), (*p, *q))}


def nees_or_nan(error: np.ndarray, cov: np.ndarray) -> float:
    """Pose NEES, NaN while the pose covariance is zero (slam's first frame fixes the gauge)."""
    return pose_nees(error, cov) if np.any(cov) else float("nan")
