"""Edge-aware smoothing of a depth image, for the normals a depth frame carries.

Raw neighbour-difference normals are noise (σ(z) is about the vertex spacing at 320x240), so they
come from smoothed depth, as KinectFusion's come from bilaterally filtered depth. Smoothing across a
depth edge would average a crate with the wall behind it and bend the normals ICP uses, so a
neighbour counts only within a ``gate`` of the pixel's depth (a separable bilateral filter with a
box range kernel):

    gate(d) = EDGE_SIGMAS · σ(d) + EDGE_SHARE · d

(the second term admits a slanted plane's own depth change).
"""

from __future__ import annotations

import numpy as np
from numba import njit

EDGE_SIGMAS = 3.0    # noise: 3 σ(z) keeps 99.7 % of the same surface's samples
EDGE_SHARE = 0.02    # slope: 2 % of the depth (4 cm at 2 m, a 70 deg slant over 2 px at 320x240)


@njit(cache=True)
def depth_gate(depth, sigma):
    """``gate(d) = EDGE_SIGMAS · σ(d) + EDGE_SHARE · d`` (m) per pixel (arrays) or for one depth
    (scalars; the depth sensor's compiled pass); ``sigma`` is σ(d)."""
    return EDGE_SIGMAS * sigma + EDGE_SHARE * depth


@njit(cache=True)
def _row_pass(depth, gate, taps, radius, num, den):
    """Per pixel x over its row: ``num(x) = Σ_b G(b) [|d(x + b) − d(x)| ≤ gate(x)] d(x + b)``,
    ``den(x)`` the same without ``d(x + b)`` (0 where ``d(x)`` is NaN). Offset outer, row inner: the
    inner loop vectorises and each pixel still sums in increasing ``b``."""
    h, w = depth.shape
    for v in range(h):
        d, g, s, t = depth[v], gate[v], num[v], den[v]
        s[:] = 0.0
        t[:] = 0.0
        for b in range(-radius, radius + 1):
            wt, lo, hi = taps[b + radius], max(0, -b), min(w, w - b)
            # slices, so the index runs from 0 and numba adds no negative-index test that stops SIMD
            here, there, gh, sh, th = d[lo:hi], d[lo + b:hi + b], g[lo:hi], s[lo:hi], t[lo:hi]
            for i in range(hi - lo):
                ok = abs(there[i] - here[i]) <= gh[i]      # a select, not a branch: the edge is unpredictable
                sh[i] += wt * there[i] if ok else 0.0
                th[i] += wt if ok else 0.0


@njit(cache=True, error_model="numpy")   # numpy's division: a pixel no neighbour passes is NaN, not an exception
def _column_pass(depth, gate, taps, radius, num, den, out):
    """Per pixel x down its column: ``out(x) = Σ_a G(a) [..] num(x + a) / Σ_a G(a) [..] den(x + a)``
    with ``_row_pass``'s gate, NaN where ``d(x)`` is NaN."""
    h, w = depth.shape
    s, t, ok = np.empty(w), np.empty(w), np.empty(w, dtype=np.bool_)
    for v in range(h):
        d, g = depth[v], gate[v]
        s[:] = 0.0
        t[:] = 0.0
        for a in range(max(-radius, -v), min(radius, h - 1 - v) + 1):
            wt, dn, rn, rd = taps[a + radius], depth[v + a], num[v + a], den[v + a]
            # the gate first, then both sums: few enough arrays per loop for LLVM's run-time overlap checks to vectorise it
            for u in range(w):
                ok[u] = abs(dn[u] - d[u]) <= g[u]
            for u in range(w):
                s[u] += wt * rn[u] if ok[u] else 0.0
                t[u] += wt * rd[u] if ok[u] else 0.0
        for u in range(w):
            out[v, u] = s[u] / t[u] if np.isfinite(d[u]) else np.nan


@njit(cache=True)
def _gated_gaussian(depth, gate, sigma_px, radius, num, den, out):
    taps = np.empty(2 * radius + 1)
    for a in range(-radius, radius + 1):
        taps[a + radius] = np.exp(-(a * a) / (2.0 * sigma_px * sigma_px))
    _row_pass(depth, gate, taps, radius, num, den)
    _column_pass(depth, gate, taps, radius, num, den, out)


def edge_aware_smoothed(depth: np.ndarray, sigma_px: float, gate: np.ndarray,
                        work: np.ndarray | None = None) -> np.ndarray:
    """The separable edge-aware Gaussian (G of ``sigma_px``, offsets within ``2σ``):

        r(x) = Σ_b G(b) [|d(x + b e_u) − d(x)| ≤ gate(x)] d(x + b e_u),   ρ(x) the same without d,
        d̃(x) = Σ_a G(a) [|d(x + a e_v) − d(x)| ≤ gate(x)] r(x + a e_v)
               / Σ_a G(a) [|d(x + a e_v) − d(x)| ≤ gate(x)] ρ(x + a e_v),

    NaN where ``depth`` is; a hole is neither filled nor pulls its neighbours. Separable rather than
    2-D: cheaper, and a pixel cannot reach around an edge's corner. ``work``: optional (3, H, W)
    scratch, the result ``work[2]``."""
    depth = np.ascontiguousarray(depth, dtype=np.float64)
    gate = np.ascontiguousarray(np.broadcast_to(gate, depth.shape), dtype=np.float64)
    num, den, out = np.empty((3, *depth.shape)) if work is None else work
    _gated_gaussian(depth, gate, float(sigma_px), int(np.ceil(2 * sigma_px)), num, den, out)
    return out


def depth_edges(depth: np.ndarray, gate: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour more than ``gate`` away in depth: their central-difference normal
    spans an edge."""
    edge = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for axis in (0, 1):
            jump = np.abs(np.diff(depth, axis=axis))
            lo = [slice(None)] * 2
            hi = [slice(None)] * 2
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            edge[tuple(lo)] |= jump > gate[tuple(lo)]
            edge[tuple(hi)] |= jump > gate[tuple(hi)]
    return edge


@njit(cache=True)
def across_edge(depth, gate, v, u):
    """``depth_edges(depth, gate)[v, u]`` for an inner pixel (NaN compares false)."""
    d, g = depth[v, u], gate[v, u]
    return (abs(depth[v - 1, u] - d) > g or abs(depth[v + 1, u] - d) > g
            or abs(depth[v, u - 1] - d) > g or abs(depth[v, u + 1] - d) > g)
