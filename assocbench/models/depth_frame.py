"""A depth frame as the dense track uses it: vertex and normal maps (OpenCV axes), per-pixel truth.
Missing depth is NaN everywhere, never 0, so no filter mistakes it for a surface at the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .camera import Intrinsics

NO_GEOM = -1   # segmentation of a pixel that sees nothing (background)


def vertex_map(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Back-projected points ``V[v, u] = d · ((u − cx)/f, (v − cy)/f, 1)`` (H, W, 3) in the camera
    frame; NaN where the depth is NaN."""
    h, w = depth.shape
    u, v = pixel_rays(K, h, w)
    d = np.asarray(depth, dtype=np.float64)
    return np.stack([d * u[None, :], d * v[:, None], d], axis=-1)


def pixel_rays(K: Intrinsics, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The ray slopes ``(u − cx)/f`` per column and ``(v − cy)/f`` per row: vertices built from them
    match ``vertex_map`` bit for bit."""
    return (np.arange(w, dtype=np.float64) - K.cx) / K.f, (np.arange(h, dtype=np.float64) - K.cy) / K.f


def normal_map(vertices: np.ndarray) -> np.ndarray:
    """The homework's neighbour cross product over both neighbours (H, W, 3), normalised, facing the
    camera:

        n = (V[v+1, u] − V[v−1, u]) × (V[v, u+1] − V[v, u−1])

    NaN on the border and where undefined. Central, not one-sided: a one-sided normal shares the
    pixel's own noise, which biases the point-to-plane residual ``n_q · (p′ − q)`` and drags ICP off
    the true pose."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    if V.ndim != 3 or V.shape[2] != 3:
        raise ValueError(f"normal_map: vertices must be (H, W, 3), got {V.shape}")
    out = np.empty(V.shape)
    _normals(V, out)
    return out


@njit(cache=True)
def _normals(V, out):
    """``out`` = ``normal_map(V)`` (its docstring), pixel by pixel (``central_normal``), NaN on the border."""
    h, w = V.shape[0], V.shape[1]
    out[:] = np.nan
    for v in range(1, h - 1):
        for u in range(1, w - 1):
            n = central_normal((V[v, u - 1, 0], V[v, u - 1, 1], V[v, u - 1, 2]),
                               (V[v, u + 1, 0], V[v, u + 1, 1], V[v, u + 1, 2]),
                               (V[v - 1, u, 0], V[v - 1, u, 1], V[v - 1, u, 2]),
                               (V[v + 1, u, 0], V[v + 1, u, 1], V[v + 1, u, 2]))
            out[v, u, 0], out[v, u, 1], out[v, u, 2] = n


@njit(cache=True)
def central_normal(left, right, up, down):
    """``n = (down − up) × (right − left) / |…|`` for 3-vectors; NaN where the norm is not > 0. The
    one formula of ``normal_map`` and the sensor's pass."""
    dx0, dx1, dx2 = right[0] - left[0], right[1] - left[1], right[2] - left[2]
    dy0, dy1, dy2 = down[0] - up[0], down[1] - up[1], down[2] - up[2]
    c0 = dy1 * dx2 - dy2 * dx1
    c1 = dy2 * dx0 - dy0 * dx2
    c2 = dy0 * dx1 - dy1 * dx0
    norm = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if norm > 0:
        return c0 / norm, c1 / norm, c2 / norm
    return np.nan, np.nan, np.nan


@njit(cache=True)
def vertex_at(depth, x, y, v, u):
    """``V[v, u] = d · (x[u], y[v], 1)`` with ``pixel_rays``' slopes: ``vertex_map``'s vertex bit
    for bit."""
    d = depth[v, u]
    return d * x[u], d * y[v], d


@dataclass
class DepthFrame:
    """One (downsampled) depth frame. Measured: ``depth`` (H, W) noisy z (m), ``vertices``,
    ``normals`` (H, W, 3), NaN where missing. Truth, for scoring only: ``true_points`` (H, W, 3),
    ``geom`` (H, W; ``NO_GEOM``: none), the true pose ``R``, ``t``.
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
