"""Predicted feature bundle ``h(x)`` of the camera track and its analytic Jacobians (lab 8, eqs. 4-9).

State perturbations around an estimate ``(R̂, p̂, l̂_j)``: camera position ``p = p̂ + δp``,
orientation ``R = R̂ Exp(δθ)`` (body-frame rotation vector), landmark ``l_j = l̂_j + δl_j``.
With ``r_c = Rᵀ (l_j - p)`` and ``h_j = (f r_x/r_z + c_x, f r_y/r_z + c_y)``:

    ∂h/∂r_c = f/r_z [[1, 0, -r_x/r_z], [0, 1, -r_y/r_z]]
    ∂r_c/∂δp = -R̂ᵀ,   ∂r_c/∂δθ = [r_c]×,   ∂r_c/∂δl_j = R̂ᵀ
"""

from __future__ import annotations

import numpy as np

from ..sim.camera import Intrinsics


def skew(v: np.ndarray) -> np.ndarray:
    """Stacked cross-product matrices ``[v]×`` of (k, 3) vectors, shape (k, 3, 3)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def predict_bundle(R: np.ndarray, p: np.ndarray, landmarks: np.ndarray,
                   K: Intrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Predicted pixels ``h`` (n, 2), Jacobians w.r.t. pose ``[δp, δθ]`` (n, 2, 6) and landmark
    ``δl_j`` (n, 2, 3), and depths ``r_z`` (n,)."""
    rc = (landmarks - p) @ R
    x, y, z = rc[:, 0], rc[:, 1], rc[:, 2]
    h = np.column_stack([K.f * x / z + K.cx, K.f * y / z + K.cy])
    dproj = np.zeros((len(rc), 2, 3))
    dproj[:, 0, 0] = dproj[:, 1, 1] = K.f / z
    dproj[:, 0, 2] = -K.f * x / z**2
    dproj[:, 1, 2] = -K.f * y / z**2
    J_l = dproj @ R.T
    J_pose = np.concatenate([-J_l, dproj @ skew(rc)], axis=2)
    return h, J_pose, J_l, z


def exp_so3(v: np.ndarray) -> np.ndarray:
    """Rotation matrix ``Exp(v)`` of a rotation vector (3,)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(v).as_matrix()


def perturb_pose(R: np.ndarray, p: np.ndarray, dp: np.ndarray, dtheta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R Exp(δθ), p + δp)``: the pose perturbation the Jacobians are taken with."""
    return R @ exp_so3(dtheta), p + dp
