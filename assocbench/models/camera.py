"""Pinhole camera: intrinsics from the MJCF and world-to-pixel projection. OpenCV axes, pixel
centres at integers; a pose ``(R, p)`` is camera-to-world. MuJoCo's camera:
``R_mujoco = R @ diag(1, -1, -1)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CV_TO_MUJOCO = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics ``f = 0.5 H / tan(fovy/2)``, ``cx = W/2 - 0.5``, ``cy = H/2 - 0.5``."""

    width: int
    height: int
    f: float
    cx: float
    cy: float

    @classmethod
    def from_fovy(cls, width: int, height: int, fovy_deg: float) -> Intrinsics:
        f = 0.5 * height / np.tan(np.deg2rad(fovy_deg) / 2)
        return cls(width, height, float(f), width / 2 - 0.5, height / 2 - 0.5)

    @property
    def area(self) -> float:
        """Image area |Y| in px^2: the measurement domain of the camera track."""
        return float(self.width * self.height)

    def in_image(self, uv: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Mask of pixels inside the image shrunk by ``margin`` pixels."""
        u, v = uv[..., 0], uv[..., 1]
        return (u >= -0.5 + margin) & (u <= self.width - 0.5 - margin) & (
            v >= -0.5 + margin) & (v <= self.height - 0.5 - margin)


def world_to_camera(points: np.ndarray, R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Camera-frame coordinates ``r_c = R^T (r - p)`` of world points (k, 3)."""
    return (np.asarray(points) - p) @ R


def project(points: np.ndarray, R: np.ndarray, p: np.ndarray, K: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``u = f x/z + cx``, ``v = f y/z + cy`` and depths ``z`` of world points (k, 3)."""
    rc = world_to_camera(points, R, p)
    z = rc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = K.f * rc[:, :2] / z[:, None] + np.array([K.cx, K.cy])
    return uv, z


def look_at(position: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera-to-world rotation of a camera at ``position`` looking at ``target``."""
    z = np.asarray(target, float) - np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, (0.0, 1.0, 0.0))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])
