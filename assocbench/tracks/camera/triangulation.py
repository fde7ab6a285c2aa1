"""Two-view DLT triangulation with its first-order covariance (GMU project 4, §I, done right).

A pose ``(R, p)``: ``R`` camera-to-world (OpenCV axes), ``p`` the centre; ``l`` is seen at
``r_c = Rᵀ (l − p)``; pose errors ``p = p̂ + δp``, ``R = R̂ Exp(δθ)``, ordered ``[δp, δθ]``. The DLT
(Hartley & Zisserman §12.2) stacks per view ``v P₃ − P₂`` and ``P₁ − u P₃`` into ``A`` (4×4) and
takes the right singular vector ``x`` of the smallest singular value, ``X = x₁:₃ / x₄``.

Its Jacobian is analytic: with ``A = U S Vᵀ`` (``x = v₄``), the implicit function theorem on
``AᵀA x = s₄² x``, ``‖x‖ = 1``, gives::

    dx = Σ_{k<4} v_k (s₄ u₄ᵀ dA v_k + s_k u_kᵀ dA v₄) / (s₄² − s_k²)
    dX = (dx₁:₃ − X dx₄) / x₄

exact for any ``A`` and finite exactly when the DLT is well posed (``s₃ > s₄``, ``x₄ ≠ 0``), with no
step size to choose and no SVD beyond the one made. A pixel moves one row of ``A`` by ``±P₃``; a
pose moves ``P`` by ``dP = −[0 | M δp]`` (``M = P₁:₃,₁:₃``) and ``dP = −K [δθ]× K⁻¹ P``. The tests
check it against central differences.

Unlike the GMU project's code: Gaussian ``σ`` propagated analytically (theirs drew uniform integer
pixels), and the side length's ``Var(d) = gᵀ Σ g``, ``g = [u, −u]``, ``u = (X₁ − X₂)/d``, with the
full 6×6 ``Σ`` (theirs squared the entries, dropped the correlations and returned a std), plus an
optional second-order term (``distance_mean_variance``).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from ...errors import UserError
from ...models.camera import Intrinsics

# s₃/s₁ below this: the null space of A is not one-dimensional (the rays coincide: zero
# baseline, or the point on the baseline), so no unique point.
_RANK_TOL = 1e-10
# |x₄| below this (x a unit vector, so ‖X‖ ≳ 1e10 m): the rays are parallel, point at infinity.
_INFINITY_TOL = 1e-10


def _finite(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape``, or a one-line UserError."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise UserError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise UserError(f"{name} has non-finite entries (NaN or inf); pass finite numbers")
    return arr


def intrinsic_matrix(K: Intrinsics | np.ndarray) -> np.ndarray:
    """``K = [[f, 0, c_x], [0, f, c_y], [0, 0, 1]]`` from ``Intrinsics`` (a 3×3 passes through)."""
    if isinstance(K, Intrinsics):
        return np.array([[K.f, 0.0, K.cx], [0.0, K.f, K.cy], [0.0, 0.0, 1.0]])
    return _finite("K", K, (3, 3))


def camera_matrix(R: np.ndarray, p: np.ndarray, K: Intrinsics | np.ndarray) -> np.ndarray:
    """Camera matrix ``P = K [Rᵀ | −Rᵀ p]`` (3×4): ``P [l; 1] ∝ [u, v, 1]``."""
    R = _finite("R", R, (3, 3))
    p = _finite("p", p, (3,))
    return intrinsic_matrix(K) @ np.column_stack([R.T, -R.T @ p])


def _rows(uv: np.ndarray, P: np.ndarray) -> np.ndarray:
    """One view's two DLT rows ``[v P₃ − P₂, P₁ − u P₃]`` (linear in ``P``)."""
    return np.stack([uv[1] * P[2] - P[1], P[0] - uv[0] * P[2]])


def _solve(uv_a, uv_b, P_a, P_b):
    """Checked inputs, ``A``'s SVD and the point: ``(A, U, s, V, X)`` with ``x = V[:, 3]``."""
    uv_a, uv_b = _finite("uv_a", uv_a, (2,)), _finite("uv_b", uv_b, (2,))
    P_a, P_b = _finite("P_a", P_a, (3, 4)), _finite("P_b", P_b, (3, 4))
    A = np.vstack([_rows(uv_a, P_a), _rows(uv_b, P_b)])
    U, s, Vt = np.linalg.svd(A)
    if s[0] == 0.0 or s[2] <= _RANK_TOL * s[0]:
        raise UserError("triangulation is degenerate: both rays are the same line (zero baseline, or the "
                        "point lies on the baseline); use two views from different centres")
    x = Vt[3]
    if abs(x[3]) <= _INFINITY_TOL:
        raise UserError("triangulation is degenerate: the rays are parallel (point at infinity); "
                        "use views with more parallax")
    return A, U, s, Vt.T, x[:3] / x[3]


def triangulate_dlt(uv_a: np.ndarray, uv_b: np.ndarray, P_a: np.ndarray, P_b: np.ndarray) -> np.ndarray:
    """World point (3,) from pixels ``uv_a``, ``uv_b`` of cameras ``P_a``, ``P_b``: ``A``'s unit
    null vector over its last coordinate. One-line UserError for non-finite input or rays that
    coincide or are parallel; a point behind a camera is returned as is (``two_view_candidates``
    checks depths).
    """
    return _solve(uv_a, uv_b, P_a, P_b)[4]


def _point_derivatives(U: np.ndarray, s: np.ndarray, V: np.ndarray, dAs: np.ndarray) -> np.ndarray:
    """``dX`` (3, m) for each ``dA`` in ``dAs`` (m, 4, 4): the SVD perturbation of the module doc."""
    x = V[:, 3]
    # c[m, k] = s₄ u₄ᵀ dA v_k + s_k u_kᵀ dA v₄ for k < 4
    c = s[3] * np.einsum("i,mij,jk->mk", U[:, 3], dAs, V[:, :3])
    c += s[:3] * np.einsum("ik,mij,j->mk", U[:, :3], dAs, x)
    dx = (c / (s[3] ** 2 - s[:3] ** 2)) @ V[:, :3].T  # (m, 4)
    return ((dx[:, :3] - np.outer(dx[:, 3], x[:3] / x[3])) / x[3]).T


def pixel_jacobian(uv_a: np.ndarray, uv_b: np.ndarray, P_a: np.ndarray, P_b: np.ndarray) -> np.ndarray:
    """``J = ∂X/∂(u_a, v_a, u_b, v_b)`` (3, 4) of ``triangulate_dlt``, analytic."""
    _, U, s, V, _ = _solve(uv_a, uv_b, P_a, P_b)
    P_a, P_b = np.asarray(P_a, float), np.asarray(P_b, float)
    dAs = np.zeros((4, 4, 4))
    # u_a, v_a, u_b, v_b sit in rows 1, 0, 3, 2 of A as −u P₃ or +v P₃ of their camera
    dAs[0, 1], dAs[1, 0] = -P_a[2], P_a[2]
    dAs[2, 3], dAs[3, 2] = -P_b[2], P_b[2]
    return _point_derivatives(U, s, V, dAs)


def pose_jacobian(uv_a: np.ndarray, uv_b: np.ndarray, P_a: np.ndarray, P_b: np.ndarray,
                  K: Intrinsics | np.ndarray) -> np.ndarray:
    """``∂X/∂[δp_a, δθ_a, δp_b, δθ_b]`` (3, 12) of ``triangulate_dlt``, analytic
    (``R = R̂ Exp(δθ)``, ``p = p̂ + δp``)."""
    _, U, s, V, _ = _solve(uv_a, uv_b, P_a, P_b)
    P_a, P_b = np.asarray(P_a, float), np.asarray(P_b, float)
    Km = intrinsic_matrix(K)
    dAs = np.zeros((12, 4, 4))
    for view, (uv, P) in enumerate(((np.asarray(uv_a, float), P_a), (np.asarray(uv_b, float), P_b))):
        for j in range(3):
            dP = np.zeros((3, 4))
            dP[:, 3] = -P[:, j]  # δp along axis j: −M e_j in the last column
            dAs[6 * view + j, 2 * view:2 * view + 2] = _rows(uv, dP)
            e = np.zeros(3)
            e[j] = 1.0
            dP = -Km @ np.cross(e, solve_triangular(Km, P).T).T  # −K [e_j]× K⁻¹ P (K upper triangular)
            dAs[6 * view + 3 + j, 2 * view:2 * view + 2] = _rows(uv, dP)
    return _point_derivatives(U, s, V, dAs)


def triangulation_covariance(uv_a: np.ndarray, uv_b: np.ndarray, P_a: np.ndarray, P_b: np.ndarray,
                             sigma_px: float, pose_cov: np.ndarray | None = None,
                             K: Intrinsics | np.ndarray | None = None) -> np.ndarray:
    """First-order covariance (3, 3) of ``triangulate_dlt``:
    ``Σ_X = σ² J Jᵀ + J_pose Σ_pose J_poseᵀ``, ``J = ∂X/∂(u_a, v_a, u_b, v_b)``; ``sigma_px`` per
    pixel coordinate, ``pose_cov`` optional (12, 12) (needs ``K``). First order holds while
    ``s ≈ √2 σ / (f · parallax)`` is small: it misses a variance excess of about ``8 s²``, and past
    s ≈ 0.25 ``X`` is a ratio whose denominator reaches zero within the noise (heavy tails, far
    underestimated).
    """
    if not (isinstance(sigma_px, (int, float, np.number)) and np.isfinite(sigma_px) and sigma_px >= 0):
        raise UserError(f"sigma_px must be a finite number >= 0, got {sigma_px!r}")
    J = pixel_jacobian(uv_a, uv_b, P_a, P_b)
    cov = sigma_px**2 * J @ J.T
    if pose_cov is not None:
        if K is None:
            raise UserError("pose_cov needs the intrinsics: pass K (Intrinsics or a 3x3 matrix)")
        S = _finite("pose_cov", pose_cov, (12, 12))
        Jp = pose_jacobian(uv_a, uv_b, P_a, P_b, K)
        cov = cov + Jp @ S @ Jp.T
    return 0.5 * (cov + cov.T)


def distance_mean_variance(X1: np.ndarray, S1: np.ndarray, X2: np.ndarray, S2: np.ndarray,
                           S12: np.ndarray | None = None, second_order: bool = False) -> tuple[float, float]:
    """Distance ``d = ‖X₁ − X₂‖`` and ``Var(d) = gᵀ Σ g = uᵀ Σ_Δ u``, ``g = [u, −u]``,
    ``u = (X₁ − X₂)/d``, ``Σ_Δ = S₁ + S₂ − S₁₂ − S₁₂ᵀ`` (``S₁₂ = Cov(X₁, X₂)``, zero if None; not
    zero when the points share uncertain poses). ``second_order=True`` adds the norm's curvature,
    with ``Σ_⊥ = (I − uuᵀ) Σ_Δ (I − uuᵀ)``: ``d + tr Σ_⊥ / (2d)`` and
    ``uᵀ Σ_Δ u + tr(Σ_⊥²) / (2d²)``, which matters when the across-side spread is not small next to
    ``√(d σ_d)`` (triangulated corners spread along their rays).
    """
    X1, X2 = _finite("X1", X1, (3,)), _finite("X2", X2, (3,))
    S1, S2 = _finite("S1", S1, (3, 3)), _finite("S2", S2, (3, 3))
    S12 = np.zeros((3, 3)) if S12 is None else _finite("S12", S12, (3, 3))
    delta = X1 - X2
    d = float(np.linalg.norm(delta))
    if d == 0.0:
        raise UserError("distance_mean_variance: X1 and X2 coincide, so the distance has no gradient; "
                        "pass two distinct points")
    u = delta / d
    S = S1 + S2 - S12 - S12.T
    var = float(u @ S @ u)
    if second_order:
        Q = np.eye(3) - np.outer(u, u)
        S_perp = Q @ S @ Q
        return d + float(np.trace(S_perp)) / (2 * d), var + float(np.sum(S_perp * S_perp)) / (2 * d * d)
    return d, var


def fundamental_matrix(R_a: np.ndarray, p_a: np.ndarray, R_b: np.ndarray, p_b: np.ndarray,
                       K: Intrinsics | np.ndarray) -> np.ndarray:
    """``F`` with ``x_bᵀ F x_a = 0`` for homogeneous pixels of one point:
    ``F = K⁻ᵀ [t]× R_ba K⁻¹``, ``R_ba = R_bᵀ R_a``, ``t = R_bᵀ (p_a − p_b)``."""
    Km = intrinsic_matrix(K)
    t = R_b.T @ (p_a - p_b)
    E = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]]) @ R_b.T @ R_a
    EKinv = solve_triangular(Km, E.T, trans="T").T  # E K⁻¹ = (K⁻ᵀ Eᵀ)ᵀ
    return solve_triangular(Km, EKinv, trans="T")  # K⁻ᵀ (E K⁻¹)


def two_view_candidates(uv_a: np.ndarray, uvs_b: np.ndarray, R_a: np.ndarray, p_a: np.ndarray,
                        R_b: np.ndarray, p_b: np.ndarray, K: Intrinsics | np.ndarray,
                        gate_px: float) -> int:
    """The frame-B feature (row of ``uvs_b``) best matching ``uv_a`` for a two-view landmark, or -1:
    nearest the epipolar line ``ℓ = F [u_a, v_a, 1]`` (``|x_bᵀ ℓ| / ‖ℓ₁:₂‖`` px) within ``gate_px``,
    its DLT point in front of both cameras. -1 when none qualifies, the centres coincide or ``uv_a``
    is the epipole. A self-similar scene may offer several along the line: gate the landmark before
    trusting it.
    """
    uv_a = _finite("uv_a", uv_a, (2,))
    uvs_b = np.asarray(uvs_b, dtype=float)
    uvs_b = _finite("uvs_b", uvs_b, uvs_b.shape if uvs_b.size == 0 else (len(uvs_b) if uvs_b.ndim else -1, 2))
    R_a, R_b = _finite("R_a", R_a, (3, 3)), _finite("R_b", R_b, (3, 3))
    p_a, p_b = _finite("p_a", p_a, (3,)), _finite("p_b", p_b, (3,))
    if not (isinstance(gate_px, (int, float, np.number)) and np.isfinite(gate_px) and gate_px > 0):
        raise UserError(f"gate_px must be a finite number > 0, got {gate_px!r}")
    scale = max(1.0, np.linalg.norm(p_a), np.linalg.norm(p_b))
    if uvs_b.size == 0 or np.linalg.norm(p_a - p_b) <= 1e-12 * scale:
        return -1
    F, x_a = fundamental_matrix(R_a, p_a, R_b, p_b, K), np.append(uv_a, 1.0)
    line = F @ x_a
    norm = np.hypot(line[0], line[1])
    if norm <= 1e-9 * np.linalg.norm(F) * np.linalg.norm(x_a):  # uv_a at the epipole: the line is rounding
        return -1
    dist = np.abs(uvs_b @ line[:2] + line[2]) / norm
    P_a, P_b = camera_matrix(R_a, p_a, K), camera_matrix(R_b, p_b, K)
    for j in np.argsort(dist, kind="stable"):
        if dist[j] > gate_px:
            break
        try:
            X = triangulate_dlt(uv_a, uvs_b[j], P_a, P_b)
        except UserError:  # this pair is degenerate (on the baseline, parallel rays): skip it
            continue
        if (R_a.T @ (X - p_a))[2] > 0 and (R_b.T @ (X - p_b))[2] > 0:
            return int(j)
    return -1
