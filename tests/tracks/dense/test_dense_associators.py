"""Dense associators (projective, kdtree): correct pairs at the true pose, every filter enforced,
bad parameters refused in one line; projective identical to its plain-numpy reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from dense_synthetic import ROOM, correct, perturb, render, room_frame, rotation, source_set

from assocbench.associators.dense import DENSE_METHODS, Pairs
from assocbench.associators.registry import make_dense_associator
from assocbench.associators.dense.projective import associate_numpy
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


def with_hole(frame, rows: slice, cols: slice):
    """A copy of ``frame`` whose pixels in the block are missing (NaN depth, vertex and normal)."""
    depth, V, N = frame.depth.copy(), frame.vertices.copy(), frame.normals.copy()
    depth[rows, cols], V[rows, cols], N[rows, cols] = np.nan, np.nan, np.nan
    return dataclasses.replace(frame, depth=depth, vertices=V, normals=N)


@pytest.mark.parametrize("name", sorted(DENSE_METHODS))
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
    # pairs that pass the strict filters, and the loose ones include pairs failing each filter
    R0, t0 = perturb(B.R, B.t, 1.0, 0.01, np.random.default_rng(3))
    strict = make_dense_associator(name, d_thr=0.02, angle_deg=10.0).associate(pts, nrm, B, R0, t0)
    loose = make_dense_associator(name, d_thr=1.0, angle_deg=180.0).associate(pts, nrm, B, R0, t0)
    dist, ang = world_pair_geometry(loose, pts, nrm, B, R0, t0)
    assert (dist >= 0.02).any() and (ang >= 10.0).any()
    keep = (dist < 0.02) & (ang < 10.0)
    np.testing.assert_array_equal(strict.source, loose.source[keep])
    np.testing.assert_array_equal(strict.pixel, loose.pixel[keep])
    dist, ang = world_pair_geometry(strict, pts, nrm, B, R0, t0)
    assert dist.max() < 0.02 and ang.max() < 10.0

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
                   {"angle_deg": 0}, {"angle_deg": 181}, {"angle_deg": float("inf")}, {"gate": 3}):
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
    assert isinstance(make_dense_associator("KDTree"), DENSE_METHODS["kdtree"])


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
            for d_thr, angle in ((0.05, 30.0), (0.01, 5.0), (10.0, 180.0)):
                assoc = make_dense_associator("projective", d_thr=d_thr, angle_deg=angle)
                got = assoc.associate(pts, nrm, frame, R0, t0)
                ref = associate_numpy(pts, nrm, frame, R0, t0, d_thr, angle)
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
