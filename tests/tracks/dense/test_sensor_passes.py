"""The depth sensor's compiled passes (``tracks.dense.sensor_passes``) against the plain numpy form
of their formulas (the steps ``depth_frame`` took before they were fused), on small random
frames with holes, depth edges, grazing surfaces, out-of-range depths and random dropouts: the
same values bit for bit (the truth's matrix product to 1e-12 m: numpy's goes through BLAS, whose
kernel, and so whose last bit, depends on the machine)."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.models.camera import Intrinsics
from assocbench.models.depth_frame import NO_GEOM, normal_map, pixel_rays, vertex_map
from assocbench.tracks.dense.depth_sensor import (
    DepthConfig,
    _frame_block,
    depth_frame,
    downsample_intrinsics,
    grazing_cosine,
    sensed_frame,
)
from assocbench.tracks.dense.depth_smoothing import depth_edges, depth_gate, edge_aware_smoothed
from assocbench.tracks.dense.sensor_passes import edge_free_normals

K = Intrinsics(40, 30, 35.0, 19.5, 14.5)


def scene_depth(seed: int) -> np.ndarray:
    """A (30, 40) noise-free depth: a slanted wall, a box in front (depth edges), a floor seen at
    a grazing angle, far pixels beyond the range, holes (nothing hit)."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:30, 0:40]
    depth = 3.0 + 0.01 * u + 0.005 * v
    depth[8:18, 10:22] = 1.5 + 0.002 * u[8:18, 10:22]         # a box: edges all round
    depth[25:, :] = 0.4 / np.maximum(v[25:, :] - 24.5, 0.01)  # a floor running away: grazing
    depth[:2, 30:] = 9.5                                       # beyond max_depth
    depth[rng.random(depth.shape) < 0.08] = np.nan             # nothing hit
    return depth.astype(np.float32)


def numpy_frame(d_true, seg, R, t, cfg, rng):
    """``depth_frame`` as numpy steps (the implementation the passes replaced), already strided."""
    d_true = d_true.astype(np.float64)
    v_true = vertex_map(d_true, K)
    true_points = v_true @ R.T + t
    geom = np.where(np.isfinite(d_true), seg.astype(np.int64), NO_GEOM)
    depth = d_true + (cfg.sigma_base + cfg.sigma_quad * np.square(d_true)) * rng.standard_normal(d_true.shape)
    drop = grazing_cosine(v_true) < np.cos(np.deg2rad(cfg.grazing_deg))
    if cfg.dropout > 0:
        drop |= rng.random(d_true.shape) < cfg.dropout
    with np.errstate(invalid="ignore"):
        drop |= ~((depth >= cfg.min_depth) & (depth <= cfg.max_depth))
    depth[drop] = np.nan
    gate = depth_gate(depth, cfg.sigma_base + cfg.sigma_quad * np.square(depth))
    smooth = edge_aware_smoothed(depth, cfg.normal_smooth_px, gate) if cfg.normal_smooth_px > 0 else depth
    normals = normal_map(vertex_map(smooth, K))
    normals[~np.isfinite(depth) | depth_edges(depth, gate)] = np.nan
    return depth, vertex_map(depth, K), normals, true_points, geom


def pose(seed: int) -> tuple[np.ndarray, np.ndarray]:
    q, _ = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    return q * np.sign(np.linalg.det(q)), np.array([0.3, -1.2, 0.7])


@pytest.mark.parametrize("cfg", [DepthConfig(downsample=1), DepthConfig(downsample=1, dropout=0.2),
                                 DepthConfig(downsample=1, normal_smooth_px=0.0, grazing_deg=60.0),
                                 DepthConfig(downsample=1, sigma_base=0.01, min_depth=1.0, max_depth=3.2)])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_fused_frame_is_the_numpy_steps_bit_for_bit(cfg, seed):
    d_true, seg = scene_depth(seed), np.random.default_rng(seed).integers(0, 9, (30, 40)).astype(np.int32)
    R, t = pose(seed)
    frame = sensed_frame(d_true, seg, R, t, K, cfg, np.random.default_rng([seed, 3, 17]))
    depth, vertices, normals, true_points, geom = numpy_frame(d_true, seg, R, t, cfg, np.random.default_rng([seed, 3, 17]))
    assert np.isnan(depth).any() and np.isfinite(normals).any()          # holes and normals both present
    for name, want in (("depth", depth), ("vertices", vertices), ("normals", normals), ("geom", geom)):
        assert np.array_equal(getattr(frame, name), want, equal_nan=True), name
    np.testing.assert_allclose(frame.true_points, true_points, rtol=0, atol=1e-12)
    assert np.array_equal(np.isnan(frame.true_points), np.isnan(true_points))


def test_a_strided_render_gives_the_frame_of_its_kept_pixels():
    """``depth_frame`` at downsample 2 is ``sensed_frame`` of every other pixel, draws included."""
    full_K = Intrinsics(80, 60, 70.0, 39.5, 29.5)
    big = np.repeat(np.repeat(scene_depth(2), 2, axis=0), 2, axis=1)
    seg = np.zeros(big.shape, np.int32)
    R, t = pose(2)
    a = depth_frame(big, seg, R, t, full_K, DepthConfig(downsample=2), np.random.default_rng(5))
    b = sensed_frame(big[::2, ::2], seg[::2, ::2], R, t, downsample_intrinsics(full_K, 2), DepthConfig(downsample=2),
                     np.random.default_rng(5))
    for name in ("depth", "vertices", "normals", "true_points", "geom"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name


def test_edge_free_normals_are_the_normal_map_of_the_smoothed_depth_without_edges():
    rng = np.random.default_rng(7)
    depth = scene_depth(7).astype(np.float64)
    smooth = depth + 0.001 * rng.standard_normal(depth.shape)
    gate = np.full(depth.shape, 0.05)
    gate[rng.random(depth.shape) < 0.1] = 0.0        # a zero gate: every differing neighbour is an edge
    out = np.empty((*depth.shape, 3))
    edge_free_normals(depth, smooth, gate, *pixel_rays(K, *depth.shape), out)
    want = normal_map(vertex_map(smooth, K))
    want[~np.isfinite(depth) | depth_edges(depth, gate)] = np.nan
    assert np.array_equal(out, want, equal_nan=True)


def test_the_frame_arrays_are_contiguous_and_do_not_overlap():
    parts = _frame_block(30, 40)
    assert parts["geom"].dtype == np.int64 and parts["vertices"].shape == (30, 40, 3)
    assert all(a.flags.c_contiguous for a in parts.values())
    names = list(parts)
    assert not any(np.shares_memory(parts[a], parts[b]) for i, a in enumerate(names) for b in names[i + 1:])


def test_a_frame_of_the_wrong_shape_is_refused_before_the_passes_read_past_it():
    R, t = pose(0)
    with pytest.raises(ValueError, match=r"must be \(30, 40\)"):
        sensed_frame(np.ones((30, 39)), np.zeros((30, 39), np.int32), R, t, K, DepthConfig(), np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"R \(3, 4\)"):
        sensed_frame(np.ones((30, 40)), np.zeros((30, 40), np.int32), np.eye(3, 4), t, K, DepthConfig(),
                     np.random.default_rng(0))
