"""The edge-aware smoothing of the depth the normals come from (``tracks.dense.depth_smoothing``):
the separable formula against a plain-Python reference, a slanted plane kept, a depth edge not
crossed, holes neither filled nor pulling their neighbours."""

from __future__ import annotations

import math

import numpy as np

from assocbench.tracks.dense.depth_smoothing import edge_aware_smoothed


def reference(depth: np.ndarray, sigma: float, gate: np.ndarray) -> np.ndarray:
    """The docstring's two sums, term by term, no shared code."""
    h, w = depth.shape
    r = math.ceil(2 * sigma)
    G = {a: math.exp(-a * a / (2 * sigma * sigma)) for a in range(-r, r + 1)}

    def row(v, u):
        num = den = 0.0
        for b in range(-r, r + 1):
            if 0 <= u + b < w and abs(depth[v, u + b] - depth[v, u]) <= gate[v, u]:
                num += G[b] * depth[v, u + b]
                den += G[b]
        return num, den

    out = np.full((h, w), np.nan)
    for v in range(h):
        for u in range(w):
            if not np.isfinite(depth[v, u]):
                continue
            num = den = 0.0
            for a in range(-r, r + 1):
                if 0 <= v + a < h and abs(depth[v + a, u] - depth[v, u]) <= gate[v, u]:
                    n, d = row(v + a, u)
                    num += G[a] * n
                    den += G[a] * d
            out[v, u] = num / den
    return out


def test_the_separable_filter_is_its_formula():
    rng = np.random.default_rng(4)
    depth = 2.0 + 0.01 * rng.standard_normal((14, 17))
    depth[:, 9:] += 0.5                       # a depth edge
    depth[rng.random(depth.shape) < 0.1] = np.nan
    gate = np.full(depth.shape, 0.05)
    np.testing.assert_allclose(edge_aware_smoothed(depth, 1.5, gate), reference(depth, 1.5, gate), rtol=0, atol=1e-12)


def test_a_slanted_plane_is_kept_and_an_edge_is_not_crossed():
    v, u = np.mgrid[0:30, 0:40]
    plane = 2.0 + 0.004 * u + 0.002 * v               # a ramp: symmetric windows keep it (away from the border)
    step = np.where(u < 20, 2.0, 2.6)                 # 60 cm apart: beyond any gate
    gate = np.full(plane.shape, 0.05)
    inner = (slice(6, -6), slice(6, -6))
    np.testing.assert_allclose(edge_aware_smoothed(plane, 3.0, gate)[inner], plane[inner], rtol=0, atol=1e-12)
    np.testing.assert_allclose(edge_aware_smoothed(step, 3.0, gate), step, rtol=0, atol=1e-12)   # not 2.3 near u = 20


def test_holes_are_neither_filled_nor_pull_their_neighbours():
    depth = np.full((20, 20), 3.0)
    depth[8:12, 8:12] = np.nan
    out = edge_aware_smoothed(depth, 3.0, np.full(depth.shape, 0.05))
    assert np.isnan(out[8:12, 8:12]).all()
    np.testing.assert_allclose(out[np.isfinite(depth)], 3.0, rtol=0, atol=1e-12)


def test_the_vectorised_passes_add_in_the_window_order_bit_for_bit():
    """The passes loop over the offset outside and the row inside (SIMD); each pixel still adds its
    terms in increasing offset, so the result is the per-pixel sums' exactly (depth edges, holes)."""
    rng = np.random.default_rng(9)
    depth = 1.0 + 3.0 * rng.random((24, 31))
    depth[:, 12:] += 0.4
    depth[rng.random(depth.shape) < 0.15] = np.nan
    gate = 0.3 * rng.random(depth.shape)
    assert np.array_equal(edge_aware_smoothed(depth, 3.0, gate), reference(depth, 3.0, gate), equal_nan=True)
