"""Dense associators (projective, kdtree): correct pairs at the true pose, every filter enforced,
bad parameters refused in one line; projective identical to its plain-numpy reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from dense_synthetic import ROOM, correct, perturb, render, room_frame, rotation, source_set

from assocbench.associators.dense import Pairs, make_dense_associator
from assocbench.associators.dense.projective import associate_numpy
from assocbench.associators.registry import DENSE_BUILTINS, builtin_class
from assocbench.errors import UserError


@pytest.fixture(scope="module")
def scene():
    """Source: the room seen from A; target: the room seen from B = A moved 2 deg / 5 cm."""
    A = room_frame()
    RB, tB = perturb(A.R, A.t, 2.0, 0.05, np.random.default_rng(7))
    return A, render(ROOM, RB, tB), source_set(A)


def world_pair_geometry(pairs: Pairs, points, normals, frame, R, t):
    """|p − q| and the normal angle (deg) of each pair, in world coordinates."""
    q = frame.vertices.reshape(-1, 3)[pairs.pixel] @ R.T + t
    nq = frame.normals.reshape(-1, 3)[pairs.pixel] @ R.T
    cos = np.clip(np.einsum("ij,ij->i", normals[pairs.source], nq), -1, 1)
    return np.linalg.norm(points[pairs.source] - q, axis=1), np.degrees(np.arccos(cos))


def visible_mask(assoc, points, frame, R, t):
    """Mask of the points ``assoc`` must count as visible (``considered``), written out
    independently: in front of the camera, projecting to a pixel of the image (a valid one for
    the projective method), and not behind that pixel's depth ``d`` by more than
    ``max(d_thr, gate_sigmas · sigma(d))`` (a missing depth hides nothing)."""
    pc = (points - t) @ R
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(frame.K.f * pc[:, 0] / pc[:, 2] + frame.K.cx + 0.5)
        v = np.floor(frame.K.f * pc[:, 1] / pc[:, 2] + frame.K.cy + 0.5)
        inside = (pc[:, 2] > 0) & (u >= 0) & (u < frame.K.width) & (v >= 0) & (v < frame.K.height)
        d = np.full(len(points), np.nan)
        d[inside] = frame.depth[v[inside].astype(int), u[inside].astype(int)]
        sigma = assoc.sigma_base + assoc.sigma_quad * d * d
        ok = inside & ~(pc[:, 2] > d + np.maximum(assoc.d_thr, assoc.gate_sigmas * sigma))
    if assoc.name == "projective":
        ok[inside] &= frame.valid[v[inside].astype(int), u[inside].astype(int)]
    return ok


def with_hole(frame, rows: slice, cols: slice):
    """A copy of ``frame`` whose pixels in the block are missing (NaN depth, vertex and normal)."""
    depth, V, N = frame.depth.copy(), frame.vertices.copy(), frame.normals.copy()
    depth[rows, cols], V[rows, cols], N[rows, cols] = np.nan, np.nan, np.nan
    return dataclasses.replace(frame, depth=depth, vertices=V, normals=N)


@pytest.mark.parametrize("name", sorted(DENSE_BUILTINS))
def test_dense_associator(name, scene):
    A, B, (pts, nrm, true_pts, geom) = scene
    assoc = make_dense_associator(name)

    # at the true pose: >= 99 % of the pairs see the same geom within 1 cm (measured 99.4-99.6 %)
    pairs = assoc.associate(pts, nrm, B, B.R, B.t)
    assert pairs.source.dtype == np.int64 and pairs.pixel.dtype == np.int64
    assert np.all(np.diff(pairs.source) > 0), "sorted, at most one pair per source point"
    assert len(pairs) > 0.9 * len(pts) and pairs.considered >= len(pairs)
    assert B.valid.reshape(-1)[pairs.pixel].all()
    assert correct(pairs, true_pts, geom, B).mean() >= 0.99

    # each filter enforced, from a guess 1 deg / 1 cm off: the strict pairs are exactly the loose
    # pairs that pass the strict filters (the gate of each pair's pixel depth, max(2 cm, 3 sigma):
    # 2-5.2 cm over the room's 1.0-2.9 m, and visibility under that gate), and the loose ones
    # include pairs failing each filter
    R0, t0 = perturb(B.R, B.t, 1.0, 0.01, np.random.default_rng(3))
    strict_assoc = make_dense_associator(name, d_thr=0.02, angle_deg=10.0)
    strict = strict_assoc.associate(pts, nrm, B, R0, t0)
    loose = make_dense_associator(name, d_thr=1.0, angle_deg=180.0).associate(pts, nrm, B, R0, t0)
    dist, ang = world_pair_geometry(loose, pts, nrm, B, R0, t0)
    gate = strict_assoc.gate(B.depth.reshape(-1)[loose.pixel])
    visible = visible_mask(strict_assoc, pts, B, R0, t0)
    assert strict.considered == visible.sum()
    assert (dist >= gate).any() and (ang >= 10.0).any()
    keep = (dist < gate) & (ang < 10.0) & visible[loose.source]
    np.testing.assert_array_equal(strict.source, loose.source[keep])
    np.testing.assert_array_equal(strict.pixel, loose.pixel[keep])
    dist, ang = world_pair_geometry(strict, pts, nrm, B, R0, t0)
    assert (dist < strict_assoc.gate(B.depth.reshape(-1)[strict.pixel])).all() and ang.max() < 10.0

    # behind the camera (mirrored through its centre: the naive projection lands on the same
    # pixel), outside the image (turned 60 deg about the camera's y axis) and NaN points never
    # pair, even with filters that would let anything else through
    ok = B.valid.reshape(-1)
    seen = B.vertices.reshape(-1, 3)[ok] @ B.R.T + B.t
    seen_n = B.normals.reshape(-1, 3)[ok] @ B.R.T
    turn = B.R @ rotation([0, 1, 0], 60.0) @ B.R.T
    bad = np.vstack([2 * B.t - seen, (seen - B.t) @ turn.T + B.t, np.full((5, 3), np.nan)])
    bad_n = np.vstack([seen_n, seen_n @ turn.T, np.full((5, 3), np.nan)])
    anything = make_dense_associator(name, d_thr=100.0, angle_deg=180.0)
    assert len(anything.associate(bad, bad_n, B, B.R, B.t)) == 0
    assert len(anything.associate(seen, seen_n, B, B.R, B.t)) > 0.99 * len(seen)

    # missing pixels never pair; a frame with none valid gives no pair and no error
    holed = with_hole(B, slice(60, 180), slice(80, 240))
    hp = anything.associate(pts, nrm, holed, B.R, B.t)
    v, u = np.divmod(hp.pixel, B.K.width)
    assert len(hp) > 0 and not np.any((v >= 60) & (v < 180) & (u >= 80) & (u < 240))
    assert len(assoc.associate(pts, nrm, with_hole(B, slice(None), slice(None)), B.R, B.t)) == 0

    # bad parameters and inputs: one-line UserErrors
    for params in ({"d_thr": 0}, {"d_thr": -0.1}, {"d_thr": float("nan")}, {"d_thr": "5cm"},
                   {"angle_deg": 0}, {"angle_deg": 181}, {"angle_deg": float("inf")}, {"gate": 3},
                   {"gate_sigmas": -1.0}, {"sigma_quad": float("nan")}):
        with pytest.raises(UserError) as err:
            make_dense_associator(name, **params)
        assert "\n" not in str(err.value) and list(params)[0] in str(err.value)
    with pytest.raises(UserError, match="(n, 3)"):
        assoc.associate(pts[:, :2], nrm[:, :2], B, B.R, B.t)
    with pytest.raises(UserError, match="DepthFrame"):
        assoc.associate(pts, nrm, B.depth, B.R, B.t)


def test_unknown_dense_method_is_one_line():
    with pytest.raises(UserError, match="did you mean projective"):
        make_dense_associator("projectiv")
    assert isinstance(make_dense_associator("KDTree"), builtin_class("kdtree"))


def test_projective_equals_plain_numpy(scene):
    """The compiled kernel and the numpy reference give identical pairs and counts: at the true
    pose, at guesses up to 10 deg / 10 cm off, with noise, a hole and tight filters."""
    A, B, (pts, nrm, _, _) = scene
    noisy = render(ROOM, B.R, B.t, sigma_base=0.0012, sigma_quad=0.0019, grazing_deg=75.0,
                   rng=np.random.default_rng([4]))
    rng = np.random.default_rng(11)
    for frame in (B, noisy, with_hole(B, slice(0, 100), slice(0, 50))):
        for deg in (0.0, 1.0, 3.0, 10.0):
            R0, t0 = perturb(B.R, B.t, deg, deg / 100, rng)
            for d_thr, angle, k in ((0.05, 30.0, 3.0), (0.01, 5.0, 0.0), (10.0, 180.0, 3.0)):
                assoc = make_dense_associator("projective", d_thr=d_thr, angle_deg=angle, gate_sigmas=k)
                got = assoc.associate(pts, nrm, frame, R0, t0)
                ref = associate_numpy(pts, nrm, frame, R0, t0, assoc)
                np.testing.assert_array_equal(got.source, ref.source)
                np.testing.assert_array_equal(got.pixel, ref.pixel)
                assert got.considered == ref.considered


def test_kdtree_builds_its_tree_once_per_frame(scene):
    A, B, (pts, nrm, _, _) = scene
    kd = make_dense_associator("kdtree")
    kd.associate(pts, nrm, B, B.R, B.t)
    tree = kd.tree(B)[0]
    kd.associate(pts, nrm, B, *perturb(B.R, B.t, 1.0, 0.01, np.random.default_rng(0)))
    assert kd.tree(B)[0] is tree
    kd.associate(pts, nrm, A, A.R, A.t)
    assert kd.tree(A)[0] is not tree


@pytest.mark.parametrize("name", sorted(DENSE_BUILTINS))
def test_considered_counts_only_visible_points_and_the_gate_grows_with_depth(name, scene):
    """Source points pushed 0.5 m behind their surface along the view ray are hidden: neither
    paired nor considered. Pulled 0.5 m in front, they are visible (the sensor sees through them)
    and considered, but unpaired. Points 6 cm in front of their surface along the ray pair where
    the pixels' depths read 4 m (gate max(5 cm, 3 σ(4 m)) = 9.5 cm), far fewer with the fixed 5 cm gate
    (none projective; kdtree finds nearer vertices sideways for 65 %)."""
    _, B, (pts, nrm, _, _) = scene
    assoc = make_dense_associator(name)
    ray = pts - B.t
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    at_truth = assoc.associate(pts, nrm, B, B.R, B.t)
    behind = assoc.associate(pts + 0.5 * ray, nrm, B, B.R, B.t)
    front = assoc.associate(pts - 0.5 * ray, nrm, B, B.R, B.t)
    assert behind.considered < 0.01 * at_truth.considered and len(behind) < 0.001 * at_truth.considered
    assert front.considered > 0.9 * at_truth.considered and len(front) < 0.001 * front.considered
    assert assoc.gate(1.0) == pytest.approx(0.05) and assoc.gate(4.0) == pytest.approx(3 * (0.0012 + 0.0019 * 16))
    far = dataclasses.replace(B, depth=np.where(np.isfinite(B.depth), 4.0, np.nan))   # gate at 4 m, same vertices
    shifted = pts - 0.06 * ray
    deep = make_dense_associator(name).associate(shifted, nrm, far, B.R, B.t)
    flat = make_dense_associator(name, gate_sigmas=0.0).associate(shifted, nrm, far, B.R, B.t)
    assert len(deep) > 0.9 * len(at_truth) and len(flat) < 0.75 * len(deep), (len(deep), len(flat))


def test_the_gates_default_noise_is_the_depth_sensors():
    """The associators' gate takes the depth sensor's default noise (models cannot import the
    track's sensor, so the numbers are written twice: this keeps them equal)."""
    from assocbench.associators.dense.base import SENSOR_SIGMA_BASE, SENSOR_SIGMA_QUAD
    from assocbench.tracks.dense.settings import DepthConfig

    assert (SENSOR_SIGMA_BASE, SENSOR_SIGMA_QUAD) == (DepthConfig().sigma_base, DepthConfig().sigma_quad)


def test_a_dense_run_passes_its_sensor_noise_to_the_gate():
    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.tracks.dense.track import gate_params

    spec = run_spec(load_run_config(None, ["depth.sigma_base=0.004"], method="projective", scene="crates", frames=3))
    assert gate_params(spec)["sigma_base"] == 0.004
    spec = run_spec(load_run_config(None, ["depth.sigma_base=0.004", "params.sigma_base=0.001"],
                                    method="projective", scene="crates", frames=3))
    assert gate_params(spec)["sigma_base"] == 0.001
