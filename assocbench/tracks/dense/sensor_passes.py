"""The depth sensor's two compiled passes over the pixels, writing preallocated outputs: ``sense``
(truth, noise, drops, vertices, the smoothing's gate) and, after the smoothing,
``edge_free_normals``. Both keep the numpy formulas' order of operations: the same frame bit for bit
(tests/tracks/dense/test_sensor_passes.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...models.depth_frame import NO_GEOM, central_normal, vertex_at
from .depth_smoothing import across_edge, depth_gate
from .fused_ops import fma


@njit(cache=True)
def axial_sigma(z, sigma_base, sigma_quad):
    """Axial noise ``σ(z) = sigma_base + sigma_quad · z²`` (m) at depth ``z`` (m; scalar or array)."""
    return sigma_base + sigma_quad * (z * z)


@njit(cache=True, error_model="numpy")   # numpy's division: 0/0 is NaN, not an exception
def view_cosine(here, right, below, own):
    """``|c · p| / sqrt(|c|² |p|²)``, ``c = (below − here) × (right − here)``, ``p = own``: the
    cosine between the view ray and the surface normal."""
    dx0, dx1, dx2 = right[0] - here[0], right[1] - here[1], right[2] - here[2]
    dy0, dy1, dy2 = below[0] - here[0], below[1] - here[1], below[2] - here[2]
    cx = dy1 * dx2 - dy2 * dx1
    cy = dy2 * dx0 - dy0 * dx2
    cz = dy0 * dx1 - dy1 * dx0
    x, y, z = own
    return abs(cx * x + cy * y + cz * z) / np.sqrt((cx * cx + cy * cy + cz * cz) * (x * x + y * y + z * z))


@njit(cache=True, error_model="numpy")
def grazing_kernel(V):
    """``out[v, u] = view_cosine(V[r, c], V[r, c+1], V[r+1, c], V[v, u])`` with ``r = min(v, h−2)``,
    ``c = min(u, w−2)`` (``depth_sensor.grazing_cosine``)."""
    h, w = V.shape[0], V.shape[1]
    out = np.empty((h, w))
    for v in range(h):
        r = min(v, h - 2)
        for u in range(w):
            c = min(u, w - 2)
            out[v, u] = view_cosine((V[r, c, 0], V[r, c, 1], V[r, c, 2]), (V[r, c + 1, 0], V[r, c + 1, 1], V[r, c + 1, 2]),
                                    (V[r + 1, c, 0], V[r + 1, c, 1], V[r + 1, c, 2]), (V[v, u, 0], V[v, u, 1], V[v, u, 2]))
    return out


@njit(cache=True, error_model="numpy")
def sense(d_true, seg, xu, yv, R, t, noise, rnd, params, depth, vertices, true_points, geom, gate):
    """One pass over the pixels, with ``z = d_true[v, u]`` and ``V = z (xu[u], yv[v], 1)`` (``vertex_at``):

        true_points = R V + t      row i as fma(z, R[i,2], fma(y, R[i,1], x R[i,0])) + t[i], the order and
                                   single roundings in which OpenBLAS's x86-64 kernel forms V @ R.T
        geom        = seg, or NO_GEOM where z is NaN
        depth       = z + σ(z) n   (axial_sigma; n = noise[v, u]), NaN where the view cosine of the
                                   noise-free surface (view_cosine, as grazing_cosine) < cos_min, where
                                   rnd[v, u] < dropout (dropout > 0), or outside [lo, hi] (NaN included)
        vertices    = depth (xu[u], yv[v], 1)
        gate        = depth_gate(depth, σ(depth))   (the edge-aware smoothing's, NaN where depth is)

    ``params`` = (sigma_base, sigma_quad, cos_min, dropout, lo, hi); ``rnd`` is read only when dropout > 0."""
    sigma_base, sigma_quad, cos_min, dropout, lo, hi = params
    h, w = d_true.shape
    for v in range(h):
        r = min(v, h - 2)
        for u in range(w):
            c = min(u, w - 2)
            x, y, z = vertex_at(d_true, xu, yv, v, u)
            for i in range(3):
                true_points[v, u, i] = fma(z, R[i, 2], fma(y, R[i, 1], x * R[i, 0])) + t[i]
            geom[v, u] = seg[v, u] if np.isfinite(z) else NO_GEOM
            m = z + axial_sigma(z, sigma_base, sigma_quad) * noise[v, u]
            cosine = view_cosine(vertex_at(d_true, xu, yv, r, c), vertex_at(d_true, xu, yv, r, c + 1),
                                 vertex_at(d_true, xu, yv, r + 1, c), (x, y, z))
            if cosine < cos_min or (dropout > 0 and rnd[v, u] < dropout) or not (lo <= m <= hi):
                m = np.nan
            depth[v, u] = m
            vertices[v, u, 0], vertices[v, u, 1], vertices[v, u, 2] = m * xu[u], m * yv[v], m
            gate[v, u] = depth_gate(m, axial_sigma(m, sigma_base, sigma_quad))


@njit(cache=True)
def edge_free_normals(depth, smooth, gate, xu, yv, out):
    """``out = normal_map(vertex_map(smooth))``, NaN where ``depth`` is NaN and where
    ``depth_edges(depth, gate)`` (``across_edge``), pixel by pixel: with ``V = vertex_at(smooth, …)``,
    ``n = (V[v+1, u] − V[v−1, u]) × (V[v, u+1] − V[v, u−1]) / |…|`` (``central_normal``), NaN on the border."""
    h, w = depth.shape
    for v in range(h):
        for u in range(w):
            inner = 0 < v < h - 1 and 0 < u < w - 1
            if inner and np.isfinite(depth[v, u]) and not across_edge(depth, gate, v, u):
                out[v, u, 0], out[v, u, 1], out[v, u, 2] = central_normal(
                    vertex_at(smooth, xu, yv, v, u - 1), vertex_at(smooth, xu, yv, v, u + 1),
                    vertex_at(smooth, xu, yv, v - 1, u), vertex_at(smooth, xu, yv, v + 1, u))
            else:
                out[v, u, 0] = out[v, u, 1] = out[v, u, 2] = np.nan
