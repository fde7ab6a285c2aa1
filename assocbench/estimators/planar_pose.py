"""The planar robot pose in an EKF, shared by the planar filters (``PlanarEKF``, ``LineEKF``): the
odometry prediction and the pose views. For ``Δ = (Δx, Δy, Δθ)`` in the previous pose's frame,
covariance Q (c, s of θ):

    x' = x + c Δx − s Δy,   y' = y + s Δx + c Δy,   θ' = wrap(θ + Δθ)
    F = [[1, 0, −s Δx − c Δy], [0, 1, c Δx − s Δy], [0, 0, 1]],   G = blockdiag(R(θ), 1)

``P' = F P Fᵀ + G Q Gᵀ`` on the pose block, ``F P`` on the cross terms
(``ekf_core.propagate_pose``).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import UserError
from ..models.se2 import compose, rz
from .base import Motion
from .ekf_core import propagate_pose


def motion_step(pose: np.ndarray, P: np.ndarray, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """``(pose ⊕ Δ, P')`` (module docstring); ``P`` is overwritten (a filter replaces its own).
    A motion that is not planar odometry is a ``UserError``."""
    inc, Q = np.asarray(motion.increment, dtype=float), np.asarray(motion.covariance, dtype=float)
    if inc.shape != (3,) or Q.shape != (3, 3):
        raise UserError(f"planar odometry needs an increment (3,) and covariance (3, 3), got {inc.shape} and "
                        f"{Q.shape}; build it with sim.odometry.planar_odometry")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    F = np.eye(3)
    F[0, 2], F[1, 2] = -s * inc[0] - c * inc[1], c * inc[0] - s * inc[1]
    G = np.eye(3)
    G[:2, :2] = [[c, -s], [s, c]]
    return compose(pose, inc), propagate_pose(P, F, G @ Q @ G.T, overwrite=True)


class PlanarPoseViews:
    """Pose views of a filter whose state and covariance start with ``(x, y, θ)``."""

    _x: np.ndarray
    P: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """``[x, y, θ]`` (3,)."""
        return self._x[:3].copy()

    @property
    def pose_covariance(self) -> np.ndarray:
        """Covariance (3, 3) of the world-frame pose error ``[δx, δy, δθ]``."""
        return self.P[:3, :3].copy()

    @property
    def R(self) -> np.ndarray:
        """The pose's rotation as a 3-D one, ``Rz(θ)`` (for code that writes 3-D poses)."""
        return rz(self._x[2])

    @property
    def p(self) -> np.ndarray:
        """The pose's position as a 3-D one, ``(x, y, 0)``."""
        return np.array([self._x[0], self._x[1], 0.0])
