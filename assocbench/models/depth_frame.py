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
    """The ray slopes ``((u − cx)/f`` for each column ``u < w``, ``(v − cy)/f`` for each row ``v < h)``:
    ``V[v, u] = d · (x[u], y[v], 1)``. Compiled passes that build vertices pixel by pixel take them from
    here, so their vertices are ``vertex_map``'s bit for bit."""
    return (np.arange(w, dtype=np.float64) - K.cx) / K.f, (np.arange(h, dtype=np.float64) - K.cy) / K.f


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
    itself out, and the same step stays within 0.1 mm. One compiled pass a pixel (``_normals``):
    the vectorised numpy form made nine temporaries of the whole map, ~4.6 ms a 320x240 frame."""
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
    """``n = (down − up) × (right − left) / |…|`` for 3-vectors (tuples): the cross product ``dy × dx``
    of the central differences, divided by its norm; NaN where that is not > 0 or a coordinate is
    NaN (NaN compares false). The one formula of ``normal_map`` and of the depth sensor's fused pass."""
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
    """``V[v, u] = d · (x[u], y[v], 1)`` with ``d = depth[v, u]`` and the slopes of ``pixel_rays``:
    ``vertex_map``'s vertex, bit for bit, without building the map."""
    d = depth[v, u]
    return d * x[u], d * y[v], d


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
