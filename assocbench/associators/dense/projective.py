"""Projective data association (the homework's ``find_projective_correspondence``): each source
point, ``p_c = Rᵀ (p − t)``, goes to its nearest pixel

    u = ⌊f x/z + cx + ½⌋,   v = ⌊f y/z + cy + ½⌋      (pixel centres at integers)

First filter (``considered``): ``z > 0``, in the image, the pixel valid, not hidden
(``z ≤ d + gate(d)``). Second: ``|p_c − V|² < gate(d)²`` and ``(Rᵀ n_p) · N > cos(angle)``, the
world filters in the camera frame (rotations keep lengths and angles; equal up to rounding). One
compiled O(n) pass, pairs in source order; ``associate_numpy`` is its numpy twin (the tests'
reference).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...models.depth_frame import DepthFrame
from .base import DenseAssociator, Pairs, checked_inputs, flat_maps


@njit(cache=True)
def projective_kernel(points, normals, depth, V, N, width, height, f, cx, cy, R, t, floor, gate_a, gate_b, cos_thr):
    """(source, pixel, considered) with ``gate(d) = max(floor, gate_a + gate_b · d²)`` (module
    docstring)."""
    n = points.shape[0]
    src = np.empty(n, np.int64)
    pix = np.empty(n, np.int64)
    k = 0
    considered = 0
    for i in range(n):
        dx, dy, dz = points[i, 0] - t[0], points[i, 1] - t[1], points[i, 2] - t[2]
        z = R[0, 2] * dx + R[1, 2] * dy + R[2, 2] * dz
        if not z > 0.0:   # also NaN
            continue
        x = R[0, 0] * dx + R[1, 0] * dy + R[2, 0] * dz
        y = R[0, 1] * dx + R[1, 1] * dy + R[2, 1] * dz
        uf = math.floor(f * x / z + cx + 0.5)
        vf = math.floor(f * y / z + cy + 0.5)
        if not (uf >= 0.0 and uf < width and vf >= 0.0 and vf < height):   # before the int cast
            continue
        j = int(vf) * width + int(uf)
        d = depth[j]
        if not (d > 0.0 and d < np.inf and math.isfinite(N[j, 0])):
            continue
        gate = max(floor, gate_a + gate_b * d * d)
        if z > d + gate:   # hidden behind the pixel's surface: not visible, not considered
            continue
        considered += 1
        ex, ey, ez = x - V[j, 0], y - V[j, 1], z - V[j, 2]          # p_c − V
        if not ex * ex + ey * ey + ez * ez < gate * gate:
            continue
        mx = R[0, 0] * normals[i, 0] + R[1, 0] * normals[i, 1] + R[2, 0] * normals[i, 2]   # Rᵀ n_p
        my = R[0, 1] * normals[i, 0] + R[1, 1] * normals[i, 1] + R[2, 1] * normals[i, 2]
        mz = R[0, 2] * normals[i, 0] + R[1, 2] * normals[i, 1] + R[2, 2] * normals[i, 2]
        if not mx * N[j, 0] + my * N[j, 1] + mz * N[j, 2] > cos_thr:
            continue
        src[k] = i
        pix[k] = j
        k += 1
    return src[:k].copy(), pix[:k].copy(), considered


class ProjectiveAssociator(DenseAssociator):
    """Nearest pixel of each source point's projection under the guess, then the homework's filters."""

    name = "projective"
    summary = "project each source point with the pose guess; nearest pixel; distance and normal-angle filters"

    def associate(self, points, normals, frame: DepthFrame, R, t) -> Pairs:
        p, n, R, t = checked_inputs(points, normals, frame, R, t)
        depth, V, N = flat_maps(frame)
        K = frame.K
        h, w = frame.depth.shape
        src, pix, considered = projective_kernel(p, n, depth, V, N, w, h, float(K.f), float(K.cx), float(K.cy),
                                                 R, t, *self.gate_coefficients, self.cos_thr)
        return Pairs(src, pix, int(considered))


def associate_numpy(points, normals, frame: DepthFrame, R, t, assoc: ProjectiveAssociator | None = None) -> Pairs:
    """``assoc.associate`` in plain numpy, operation for operation (the tests' and benchmark's
    reference)."""
    assoc = ProjectiveAssociator() if assoc is None else assoc
    floor, gate_a, gate_b = assoc.gate_coefficients
    p, n, R, t = checked_inputs(points, normals, frame, R, t)
    depth, V, N = flat_maps(frame)
    K, (h, w) = frame.K, frame.depth.shape
    d = p - t
    z = R[0, 2] * d[:, 0] + R[1, 2] * d[:, 1] + R[2, 2] * d[:, 2]
    x = R[0, 0] * d[:, 0] + R[1, 0] * d[:, 1] + R[2, 0] * d[:, 2]
    y = R[0, 1] * d[:, 0] + R[1, 1] * d[:, 1] + R[2, 1] * d[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(float(K.f) * x / z + float(K.cx) + 0.5)
        v = np.floor(float(K.f) * y / z + float(K.cy) + 0.5)
        src = np.flatnonzero((z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h))
        pix = v[src].astype(np.int64) * w + u[src].astype(np.int64)
        dj = depth[pix]
        gate = np.maximum(floor, gate_a + gate_b * dj * dj)
        ok = (dj > 0) & (dj < np.inf) & np.isfinite(N[pix, 0]) & ~(z[src] > dj + gate)
    src, pix, gate = src[ok], pix[ok], gate[ok]
    Vj, Nj, ns = V[pix], N[pix], n[src]
    e = [c[src] - Vj[:, r] for r, c in enumerate((x, y, z))]
    m = [R[0, r] * ns[:, 0] + R[1, r] * ns[:, 1] + R[2, r] * ns[:, 2] for r in range(3)]
    cos_thr = assoc.cos_thr
    with np.errstate(invalid="ignore"):
        keep = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < gate * gate) & (
            m[0] * Nj[:, 0] + m[1] * Nj[:, 1] + m[2] * Nj[:, 2] > cos_thr)
    return Pairs(src[keep], pix[keep], len(src))
