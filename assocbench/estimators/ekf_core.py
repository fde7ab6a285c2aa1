"""The EKF's covariance algebra, shared by every track's filter.

The state is a pose block (``q`` error-state coordinates) followed by the map's landmarks
(``s`` coordinates each): ``x = [ξ, l₁, …, l_N]``, covariance ``P`` of size q + sN. Only the
algebra lives here; each track's filter supplies its motion and measurement Jacobians.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve


class NotPositiveDefinite(ArithmeticError):
    """An innovation covariance that is not positive definite (the update is refused)."""


def propagate_pose(P: np.ndarray, F: np.ndarray, GQG: np.ndarray) -> np.ndarray:
    """Prediction of a static map: with ``ξ' = f(ξ, u)`` and ``F = ∂f/∂ξ``,

        P_ξξ' = F P_ξξ Fᵀ + G Q Gᵀ,   P_ξL' = F P_ξL,   P_LL' = P_LL

    (landmarks do not move). ``GQG`` is the motion noise already mapped into the pose's
    coordinates. Works in place on a copy; costs O(q² N)."""
    q = len(F)
    out = P.copy()
    out[:q, :q] = F @ P[:q, :q] @ F.T + GQG
    out[:q, q:] = F @ P[:q, q:]
    out[q:, :q] = out[:q, q:].T
    return out


def joseph_update(P: np.ndarray, H: np.ndarray, cols: np.ndarray, innovation: np.ndarray,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """EKF update in Joseph form with a sparse measurement Jacobian.

    ``H`` (k, c) holds the nonzero columns ``cols`` of the full Jacobian (pose and the paired
    landmarks only). With ``U = P Hᵀ`` (n, k), ``S = H P Hᵀ + R = L Lᵀ`` and ``K = U S⁻¹``
    (two triangular solves with L, never an inverse):

        δx = K ν,   P' = (I − KH) P (I − KH)ᵀ + K R Kᵀ = P − K Uᵀ − U Kᵀ + K S Kᵀ.

    The Joseph form is the sum of two positive semidefinite terms, and its error is second order
    in an error of K (the short form P − KUᵀ is first order), which matters when the gain comes
    from a covariance that rounding has already touched. Expanding it as above avoids the dense
    n × n product with (I − KH), so an update costs O(n² k) like the short form. Returns
    ``(δx, P')``; raises ``NotPositiveDefinite`` when S is not."""
    U = P[:, cols] @ H.T
    S = H @ U[cols] + R
    S = 0.5 * (S + S.T)
    try:
        factor = cho_factor(S, lower=True, check_finite=True)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise NotPositiveDefinite(f"innovation covariance is not positive definite ({exc})") from None
    K = cho_solve(factor, U.T).T
    KU = K @ U.T
    P_new = P - KU - KU.T + K @ S @ K.T
    return K @ innovation, 0.5 * (P_new + P_new.T)


def augment(P: np.ndarray, J_state: np.ndarray, state_cols: np.ndarray, J_meas: np.ndarray,
            M: np.ndarray) -> np.ndarray:
    """Append a landmark ``l = g(x, m)`` initialised from the state and a measurement ``m ~ (m̂, M)``:

        P_ll = J_x P_xx J_xᵀ + J_m M J_mᵀ,   P_lx = J_x P_x·,

    with ``J_state`` the nonzero columns ``state_cols`` of ``J_x = ∂g/∂x``. Returns the grown P."""
    n, s = len(P), len(J_state)
    cross = J_state @ P[state_cols, :]
    out = np.zeros((n + s, n + s))
    out[:n, :n] = P
    out[n:, :n] = cross
    out[:n, n:] = cross.T
    block = cross[:, state_cols] @ J_state.T + J_meas @ M @ J_meas.T
    out[n:, n:] = 0.5 * (block + block.T)
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
