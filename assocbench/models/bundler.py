"""The Bundler camera (Snavely's Bundler v0.3): a pinhole with two radial distortion terms, and the
predicted bundle ``h(x)`` with its analytic Jacobians, the photos track's measurement model.

A world point ``X`` has camera coordinates ``P = R X + t`` (looking along ``-z``, y up), projects to
``q = -P_xy / P_z`` and, distorted, to ``h' = f r(q) q``, ``r(q) = 1 + k₁‖q‖² + k₂‖q‖⁴`` (px from
the centre, y up); in (column, row) pixels of a ``W × H`` image:

    h = (h'_x + (W-1)/2,  (H-1)/2 - h'_y)

Perturbations as ``pinhole``'s: ``C = C' Exp(δθ)`` (``C = Rᵀ``), ``p = p' + δp`` (``p = -Rᵀ t``),
``l = l' + δl``. With ``P = Cᵀ (l - p)``:

    ∂P/∂δp = -Cᵀ,   ∂P/∂δθ = [P]×,   ∂P/∂δl = Cᵀ
    ∂q/∂P  = -1/P_z [[1, 0, -P_x/P_z], [0, 1, -P_y/P_z]]
    ∂h'/∂q = f (r(q) I + 2 (k₁ + 2 k₂ ‖q‖²) q qᵀ),      ∂h/∂h' = diag(1, -1)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pinhole import skew

FLIP_Y = np.diag([1.0, -1.0])   # image rows go down, Bundler's y goes up


@dataclass(frozen=True)
class BundlerCamera:
    """One camera of a Bundler file: focal length ``f`` (px), radial distortion ``k1``, ``k2``,
    world-to-camera rotation ``R`` (3, 3) and translation ``t`` (3,), and its image's size."""

    f: float
    k1: float
    k2: float
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int

    @property
    def centre(self) -> np.ndarray:
        """The camera centre in the world, ``-Rᵀ t``."""
        return -self.R.T @ self.t

    @property
    def orientation(self) -> np.ndarray:
        """Camera-to-world rotation ``C = Rᵀ`` (the state's orientation)."""
        return self.R.T

    @property
    def area(self) -> float:
        """The image's area in px², the measurement domain |Y|."""
        return float(self.width * self.height)

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Bundler image coordinates (from the centre, y up) as (column, row) pixels."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        return np.column_stack([xy[:, 0] + (self.width - 1) / 2, (self.height - 1) / 2 - xy[:, 1]])

    def in_image(self, pixels: np.ndarray) -> np.ndarray:
        """Which (column, row) pixels lie in the image (centres 0..W-1, 0..H-1, half a pixel of
        border)."""
        col, row = pixels[:, 0], pixels[:, 1]
        return (col >= -0.5) & (col <= self.width - 0.5) & (row >= -0.5) & (row <= self.height - 0.5)


def predict_bundle(C: np.ndarray, p: np.ndarray, landmarks: np.ndarray,
                   camera: BundlerCamera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Predicted pixels ``h`` (n, 2) of ``landmarks`` (n, 3) from orientation ``C`` and centre
    ``p``; Jacobians to the pose ``[δp, δθ]`` (n, 2, 6) and each landmark (n, 2, 3); depths ``-P_z``
    (n,), positive in front."""
    P = (landmarks - p) @ C                      # rows: Cᵀ (l - p)
    z = P[:, 2]
    q = -P[:, :2] / z[:, None]
    r2 = np.einsum("ij,ij->i", q, q)
    radial = 1.0 + camera.k1 * r2 + camera.k2 * r2 * r2
    h = camera.to_pixels(camera.f * radial[:, None] * q)
    dq = np.zeros((len(P), 2, 3))
    dq[:, 0, 0] = dq[:, 1, 1] = -1.0 / z
    dq[:, :, 2] = P[:, :2] / z[:, None] ** 2
    slope = 2.0 * (camera.k1 + 2.0 * camera.k2 * r2)
    dh = camera.f * (radial[:, None, None] * np.eye(2) + slope[:, None, None] * q[:, :, None] * q[:, None, :])
    dP = FLIP_Y @ dh @ dq                        # ∂h/∂P (n, 2, 3)
    J_l = dP @ C.T
    J_pose = np.concatenate([-J_l, dP @ skew(P)], axis=2)
    return h, J_pose, J_l, -z
