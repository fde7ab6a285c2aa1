"""The EKF's covariance algebra, shared by every track's filter: the state is a pose block (``q``
error-state coordinates) then the landmarks (``s`` each), ``x = [ξ, l₁, …, l_N]``, covariance ``P``
(q + sN). Each track's filter supplies its Jacobians.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg.blas import dsyr2k
from scipy.linalg.lapack import dpotrs

from ..errors import UserError
from ..models.range_bearing import wrap


def paired_innovations(association: np.ndarray, n: int, z: np.ndarray, zhat: np.ndarray,
                       angular: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(a, paired, ν)``: the candidates paired (``a_j ≥ 0``) and their innovations
    ``ν_j = z_{a_j} − ẑ_j`` (k, d), angular dims wrapped; a shape other than (n,) is a one-line
    ``UserError``."""
    a = np.asarray(association, dtype=np.int64)
    if a.shape != (n,):
        raise UserError(f"association has shape {a.shape}, expected ({n},): one entry per candidate")
    paired = np.flatnonzero(a >= 0)
    nu = z[a[paired]] - zhat[paired]
    for dim in angular:
        nu[:, dim] = wrap(nu[:, dim])
    return a, paired, nu


class NotPositiveDefinite(ArithmeticError):
    """An innovation covariance that is not positive definite (the update is refused)."""


def propagate_pose(P: np.ndarray, F: np.ndarray, GQG: np.ndarray, overwrite: bool = False) -> np.ndarray:
    """Prediction of a static map, with ``ξ' = f(ξ, u)`` and ``F = ∂f/∂ξ``:

        P_ξξ' = F P_ξξ Fᵀ + G Q Gᵀ,   P_ξL' = F P_ξL,   P_LL' = P_LL

    ``GQG``: the motion noise in the pose's coordinates. ``overwrite`` works on ``P`` itself (saves
    an O(N²) copy; the rest is O(q² N))."""
    q = len(F)
    out = P if overwrite else P.copy()
    out[:q, :q] = F @ P[:q, :q] @ F.T + GQG
    out[:q, q:] = F @ P[:q, q:]
    out[q:, :q] = out[:q, q:].T
    return out


def joseph_update(P: np.ndarray, H: np.ndarray, cols: np.ndarray, innovation: np.ndarray,
                  R: np.ndarray, overwrite: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """EKF update in Joseph form with a sparse measurement Jacobian ``H`` (k, c), the nonzero
    columns ``cols`` (pose and paired landmarks). With ``U = P Hᵀ``, ``S = H P Hᵀ + R = L Lᵀ`` and
    ``K = U S⁻¹`` (two triangular solves, no inverse):

        δx = K ν,   P' = (I − KH) P (I − KH)ᵀ + K R Kᵀ = P − K Uᵀ − U Kᵀ + K S Kᵀ
                                                     = P + K Mᵀ + M Kᵀ,   M = ½ K S − U.

    The Joseph form is a sum of positive semidefinite terms and its error is second order in an
    error of K (the short form P − KUᵀ is first order); both expansions are the same polynomial in
    the computed K, so that holds. The last is a symmetric rank-2k update (BLAS ``syr2k``): no O(n³)
    product with (I − KH), one triangle (n²k multiply-adds), P' exactly symmetric, one n × n copy
    (none with ``overwrite`` and a C-ordered float64 P). Returns ``(δx, P')``; raises
    ``NotPositiveDefinite`` when S is not (P untouched)."""
    U = P[:, cols] @ H.T
    S = H @ U[cols] + R
    S = 0.5 * (S + S.T)
    if not np.all(np.isfinite(S)):
        raise NotPositiveDefinite("innovation covariance is not positive definite (it has NaN or inf entries)")
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError as exc:
        raise NotPositiveDefinite(f"innovation covariance is not positive definite ({exc})") from None
    Kt, info = dpotrs(L, U.T, lower=1)   # Kᵀ = S⁻¹ Uᵀ: L Lᵀ Kᵀ = Uᵀ, two triangular solves
    if info != 0:
        raise NotPositiveDefinite(f"innovation covariance is not positive definite (potrs info {info})")
    K = Kt.T
    M = 0.5 * (K @ S) - U
    # P is symmetric, so its transpose is the column-major array BLAS wants (no copy). syr2k
    # writes the column-major lower triangle, which is the row-major upper one of P'.
    P_new = dsyr2k(1.0, K, M, beta=1.0, c=P.T, trans=0, lower=1, overwrite_c=overwrite).T
    return K @ innovation, mirror_upper(P_new)


def mirror_upper(C: np.ndarray, block: int = 64) -> np.ndarray:
    """Copy the upper triangle of square ``C`` onto its lower one in place, ``block`` rows at a time
    (a block's transposed read stays in cache). Returns ``C``."""
    n = len(C)
    for i in range(0, n, block):
        C[i:i + block, :i] = C[:i, i:i + block].T
        D = C[i:i + block, i:i + block]
        lo = _strict_lower(len(D))
        D[lo] = D.T[lo]
    return C


@lru_cache(maxsize=8)
def _strict_lower(b: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the strictly lower triangle of a b × b block (cached: the same few sizes recur)."""
    return np.tril_indices(b, -1)


def augment(P: np.ndarray, J_state: np.ndarray, state_cols: np.ndarray, J_meas: np.ndarray,
            M: np.ndarray) -> np.ndarray:
    """Append a landmark ``l = g(x, m)`` from the state and a measurement ``m ~ (m̂, M)``:

        P_ll = J_x P_xx J_xᵀ + J_m M J_mᵀ,   P_lx = J_x P_x·,

    ``J_state``: the nonzero columns ``state_cols`` of ``J_x``. Returns the grown P."""
    n, s = len(P), len(J_state)
    cross = J_state @ P[state_cols, :]
    out = np.zeros((n + s, n + s))
    out[:n, :n] = P
    out[n:, :n] = cross
    out[:n, n:] = cross.T
    block = cross[:, state_cols] @ J_state.T + J_meas @ M @ J_meas.T
    out[n:, n:] = 0.5 * (block + block.T)
    return out


def bundle_jacobian(J_pose: np.ndarray, J_l: np.ndarray) -> np.ndarray:
    """H (d·k, q + s·k) of k predictions over ``[pose, their landmarks]``: ``J_pose`` (k, d, q) in
    the pose columns, ``J_l`` (k, d, s) block-diagonal."""
    k, d, q = J_pose.shape
    s = J_l.shape[2]
    H = np.zeros((d * k, q + s * k))
    H[:, :q] = J_pose.reshape(d * k, q)
    j = np.arange(k)
    H[:, q:].reshape(k, d, k, s)[j, :, j, :] = J_l   # the (d, s) blocks on the diagonal
    return H


def state_columns(q: int, s: int, rows: np.ndarray) -> np.ndarray:
    """State columns of the pose (``0..q-1``) and the landmarks ``rows`` (``s`` each, after the pose)."""
    lm = (q + s * np.asarray(rows, dtype=np.int64)[:, None] + np.arange(s)).ravel()
    return np.concatenate([np.arange(q), lm]).astype(np.int64)


def block_diag(blocks: np.ndarray) -> np.ndarray:
    """Block-diagonal matrix of k (d, d) blocks."""
    k, d, _ = blocks.shape
    out = np.zeros((k * d, k * d))
    j = np.arange(k)
    out.reshape(k, d, k, d)[j, :, j, :] = blocks
    return out


def remove(P: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """P without the rows and columns ``cols`` (marginalising landmarks out of a Gaussian)."""
    keep = np.setdiff1d(np.arange(len(P)), cols)
    return P[np.ix_(keep, keep)]


def is_positive_definite(P: np.ndarray) -> bool:
    """Whether a Cholesky factor of ``P`` exists (and P is finite)."""
    if not np.all(np.isfinite(P)):
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True
