"""Range-bearing measurement of a 2-D point landmark from a planar robot (the lecture's EKF-SLAM
model). Pose ``(x, y, θ)``, landmark ``l``; ``δ = l − (x, y)``, ``q = ‖δ‖²``:

    h(x, l) = ( √q,  wrap(atan2(δ_y, δ_x) − θ) )

    ∂h/∂(x, y, θ) = [[−δ_x/√q, −δ_y/√q,  0],      ∂h/∂l = [[ δ_x/√q, δ_y/√q],
                     [ δ_y/q,  −δ_x/q,  −1]]                [−δ_y/q,  δ_x/q ]]

The inverse (a landmark from ``z = (r, φ)``) is ``g(x, z) = (x + r cos(θ + φ), y + r sin(θ + φ))``:

    ∂g/∂(x, y, θ) = [[1, 0, −r sin(θ + φ)], [0, 1, r cos(θ + φ)]],
    ∂g/∂(r, φ)    = [[cos(θ + φ), −r sin(θ + φ)], [sin(θ + φ), r cos(θ + φ)]].

Pose errors are additive on ``(x, y, θ)``, θ wrapped.
"""

from __future__ import annotations

import numpy as np

ANGULAR = (1,)   # the bearing wraps: the Problem's angular dims


def wrap(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) wrapped to [−π, π)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def _offsets(pose: np.ndarray, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    L = np.asarray(landmarks, dtype=np.float64).reshape(-1, 2)
    d = L - np.asarray(pose, dtype=np.float64)[:2]
    q = np.einsum("ij,ij->i", d, d)
    return d, q, np.sqrt(q)


def predict(pose: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """``h(x, l_j)`` for every landmark: (n, 2) rows ``(range, bearing)``."""
    d, _, r = _offsets(pose, landmarks)
    return np.column_stack([r, wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])])


def jacobians(pose: np.ndarray, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(∂h/∂pose (n, 2, 3), ∂h/∂l (n, 2, 2))`` at each landmark (module docstring). A landmark
    at the robot's position has no bearing: ``ValueError``."""
    d, q, r = _offsets(pose, landmarks)
    if np.any(q <= 0):
        raise ValueError("a landmark lies at the robot's position: its bearing is undefined")
    H_l = np.empty((len(d), 2, 2))
    H_l[:, 0, 0], H_l[:, 0, 1] = d[:, 0] / r, d[:, 1] / r
    H_l[:, 1, 0], H_l[:, 1, 1] = -d[:, 1] / q, d[:, 0] / q
    H_pose = np.zeros((len(d), 2, 3))
    H_pose[:, :, :2] = -H_l
    H_pose[:, 1, 2] = -1.0
    return H_pose, H_l


def inverse(pose: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``g(x, z)``: the landmark (2,) that measurement ``z = (r, φ)`` places, in the world."""
    a = pose[2] + z[1]
    return np.array([pose[0] + z[0] * np.cos(a), pose[1] + z[0] * np.sin(a)])


def inverse_jacobians(pose: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(∂g/∂pose (2, 3), ∂g/∂z (2, 2))`` (module docstring)."""
    a = pose[2] + z[1]
    c, s = np.cos(a), np.sin(a)
    G_pose = np.array([[1.0, 0.0, -z[0] * s], [0.0, 1.0, z[0] * c]])
    G_z = np.array([[c, -z[0] * s], [s, z[0] * c]])
    return G_pose, G_z


def pose_error(true_pose: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """``[x − x̂, y − ŷ, wrap(θ − θ̂)]``: the error the planar estimators' covariances describe."""
    e = np.asarray(true_pose, dtype=np.float64) - np.asarray(estimate, dtype=np.float64)
    e[2] = wrap(e[2])
    return e
