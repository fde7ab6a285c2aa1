"""Edge-aware smoothing of a depth image, for the normals a depth frame carries.

Neighbour-difference normals of raw depth are noise (at 320x240 the sensor's σ(z) is about the
spacing of neighbouring vertices), so they are taken from smoothed depth, as KinectFusion takes
them from bilaterally filtered depth. The smoothing must not cross depth edges: a plain Gaussian
averages a crate's front with the wall behind it, bends every normal within a few pixels of the
edge, and ICP registered two noise-free crates frames (11 cm, 7 deg apart) 4.4 mm off with it,
0.05 mm without.
So a neighbour counts only when its depth is within a ``gate`` of the pixel's own (a bilateral
filter with a box range kernel, applied separably: along the row, then down the column,
``edge_aware_smoothed``), and the gate follows the sensor's noise:
``gate(d) = EDGE_SIGMAS · σ(d) + EDGE_SHARE · d`` (the second term admits a slanted plane's own
depth change across the kernel; symmetric truncation of a ramp keeps its mean).
"""

from __future__ import annotations

import numpy as np
from numba import njit

EDGE_SIGMAS = 3.0    # noise: 3 σ(z) keeps 99.7 % of the same surface's samples
EDGE_SHARE = 0.02    # slope: 2 % of the depth (4 cm at 2 m, a 70 deg slant over 2 px at 320x240)


def depth_gate(depth: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """``gate(d) = EDGE_SIGMAS · σ(d) + EDGE_SHARE · d`` (m) per pixel; ``sigma`` is σ(d)."""
    return EDGE_SIGMAS * sigma + EDGE_SHARE * depth


@njit(cache=True)
def _row_pass(depth, gate, taps, radius):
    """Per pixel x, over its row: ``num(x) = Σ_b G(b) [|d(x + b) − d(x)| ≤ gate(x)] d(x + b)`` and
    ``den(x)`` the same without ``d(x + b)`` (0, 0 where ``d(x)`` is NaN; a NaN neighbour compares false)."""
    h, w = depth.shape
    num, den = np.zeros((h, w)), np.zeros((h, w))
    for v in range(h):
        row = depth[v]
        for u in range(w):
            d = row[u]
            if not np.isfinite(d):
                continue
            g = gate[v, u]
            s = t = 0.0
            for b in range(max(-radius, -u), min(radius, w - 1 - u) + 1):
                dj = row[u + b]
                ok = abs(dj - d) <= g            # selects, not a branch: the edge is unpredictable
                wt = taps[b + radius] if ok else 0.0
                s += wt * dj if ok else 0.0
                t += wt
            num[v, u], den[v, u] = s, t
    return num, den


@njit(cache=True)
def _gated_gaussian(depth, gate, sigma_px, radius):
    h, w = depth.shape
    taps = np.empty(2 * radius + 1)
    for a in range(-radius, radius + 1):
        taps[a + radius] = np.exp(-(a * a) / (2.0 * sigma_px * sigma_px))
    num, den = _row_pass(depth, gate, taps, radius)
    out = np.full((h, w), np.nan)
    for v in range(h):
        a0, a1 = max(-radius, -v), min(radius, h - 1 - v)
        for u in range(w):
            d = depth[v, u]
            if not np.isfinite(d):
                continue
            g = gate[v, u]
            s = t = 0.0
            for a in range(a0, a1 + 1):
                if abs(depth[v + a, u] - d) <= g:
                    s += taps[a + radius] * num[v + a, u]
                    t += taps[a + radius] * den[v + a, u]
            out[v, u] = s / t
    return out


def edge_aware_smoothed(depth: np.ndarray, sigma_px: float, gate: np.ndarray) -> np.ndarray:
    """The separable edge-aware Gaussian: along the row, then down the column,

        r(x) = Σ_b G(b) [|d(x + b e_u) − d(x)| ≤ gate(x)] d(x + b e_u),   ρ(x) the same without d,
        d̃(x) = Σ_a G(a) [|d(x + a e_v) − d(x)| ≤ gate(x)] r(x + a e_v)
               / Σ_a G(a) [|d(x + a e_v) − d(x)| ≤ gate(x)] ρ(x + a e_v),

    over offsets within ``2σ`` px (G: Gaussian of ``sigma_px``; G(a) G(b) is the 2-D Gaussian),
    NaN where ``depth`` is NaN. A hole neither pulls its neighbours to 0 nor is filled, and a
    pixel across a depth edge from the pixel (along the row) or from its column neighbour (which
    is itself within the gate) does not count. Two 13-tap passes instead of one of 13 x 13 taps
    (at 3 px): 3-7 ms a 320x240 frame against 27 ms for the 2-D window on a loaded core, and on
    crates frames 10 and 50 normals closer to the truth (median 1.60 / 1.50 deg, p95 7.9 / 6.0 deg,
    against 1.72 / 1.56 and 15.8 / 10.9 for the 2-D window, which lets a pixel reach around an
    edge's corner to a surface its row and column do not touch)."""
    depth = np.ascontiguousarray(depth, dtype=np.float64)
    gate = np.ascontiguousarray(np.broadcast_to(gate, depth.shape), dtype=np.float64)
    return _gated_gaussian(depth, gate, float(sigma_px), int(np.ceil(2 * sigma_px)))


def depth_edges(depth: np.ndarray, gate: np.ndarray) -> np.ndarray:
    """(H, W) pixels with a 4-neighbour whose depth differs from theirs by more than ``gate``: a
    central-difference normal there spans a depth edge, and is dropped."""
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
