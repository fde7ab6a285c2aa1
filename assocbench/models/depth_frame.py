"""A depth frame as the dense track uses it: vertex and normal maps, and per-pixel truth.

Conventions are the camera track's (``sim/camera.py``): OpenCV camera axes (x right, y down,
z forward), a pose ``(R, t)`` is camera-to-world, pixel centres at integer coordinates. A pixel
``(v, u)`` (row, column) with z-depth ``d`` has the vertex ``V = d · ((u − cx)/f, (v − cy)/f, 1)``.
Missing depth is NaN everywhere (depth, vertex, normal), never 0, so no filter can mistake it for
a surface at the camera centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Intrinsics

NO_GEOM = -1   # segmentation of a pixel that sees nothing (background)


def vertex_map(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Back-projected points ``V[v, u] = d · ((u − cx)/f, (v − cy)/f, 1)`` (H, W, 3) in the camera
    frame; NaN where the depth is NaN."""
    h, w = depth.shape
    u = (np.arange(w, dtype=np.float64) - K.cx) / K.f
    v = (np.arange(h, dtype=np.float64) - K.cy) / K.f
    d = np.asarray(depth, dtype=np.float64)
    return np.stack([d * u[None, :], d * v[:, None], d], axis=-1)


def normal_map(vertices: np.ndarray) -> np.ndarray:
    """The homework's neighbour cross product, taken over both neighbours (H, W, 3):
    ``n = (V[v+1, u] − V[v−1, u]) × (V[v, u+1] − V[v, u−1])``, normalised. In this order (OpenCV
    axes) the normal of a surface seen from the front points towards the camera (``n · V < 0``).
    NaN on the border rows and columns and wherever a vertex involved is missing or the cross
    product vanishes.

    Why central, not the one-sided ``V[v+1, u] − V[v, u]``: a one-sided normal depends on the
    pixel's own depth, so its error is correlated with the pixel's own noise, and the
    point-to-plane residual ``n_q · (p′ − q)`` then has a systematic part (the product of the
    two errors): on crates with the sensor's noise, one ICP step from the TRUE pose moved 8 mm
    away and further each iteration (0.5 m after 60). The central difference leaves the pixel
    itself out, and the same step stays within 0.1 mm. The cross product is written out per
    component (``np.cross`` takes several times longer)."""
    n = np.full(vertices.shape, np.nan)
    dx = vertices[1:-1, 2:] - vertices[1:-1, :-2]
    dy = vertices[2:, 1:-1] - vertices[:-2, 1:-1]
    c = np.stack([dy[..., 1] * dx[..., 2] - dy[..., 2] * dx[..., 1],
                  dy[..., 2] * dx[..., 0] - dy[..., 0] * dx[..., 2],
                  dy[..., 0] * dx[..., 1] - dy[..., 1] * dx[..., 0]], axis=-1)
    norm = np.sqrt(np.einsum("...i,...i->...", c, c))[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        n[1:-1, 1:-1] = np.where(norm > 0, c / norm, np.nan)
    return n


@dataclass
class DepthFrame:
    """One (downsampled) depth frame and its truth.

    Measured (what an associator and ICP may use): ``depth`` (H, W) noisy z in metres, NaN where
    missing; ``vertices`` and ``normals`` (H, W, 3) in the camera frame, NaN where invalid.
    Truth (for scoring only): ``true_points`` (H, W, 3) world point each pixel sees, from the
    noise-free depth and the true pose, NaN where nothing is hit; ``geom`` (H, W) int MuJoCo geom
    id the pixel sees, ``NO_GEOM`` where none; ``R``, ``t`` the true camera-to-world pose.
    """

    K: Intrinsics
    depth: np.ndarray
    vertices: np.ndarray
    normals: np.ndarray
    true_points: np.ndarray
    geom: np.ndarray
    R: np.ndarray
    t: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(H, W) pixels with a vertex and a normal: the only ones an associator may pair."""
        return np.isfinite(self.depth) & np.isfinite(self.normals[..., 0])

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth.shape
