"""The compiled ``normal_map`` against the homework's formula written in numpy."""

import numpy as np

from assocbench.models.camera import Intrinsics
from assocbench.models.depth_frame import normal_map, vertex_map


def normal_map_numpy(vertices: np.ndarray) -> np.ndarray:
    """``(V[v+1,u] − V[v−1,u]) × (V[v,u+1] − V[v,u−1])``, normalised; NaN on the border, where a
    neighbour is missing and where the cross product vanishes (the vectorised form it replaced)."""
    n = np.full(vertices.shape, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):   # inf − inf: NaN, as missing
        dx = vertices[1:-1, 2:] - vertices[1:-1, :-2]
        dy = vertices[2:, 1:-1] - vertices[:-2, 1:-1]
        c = np.cross(dy, dx)
        norm = np.linalg.norm(c, axis=-1, keepdims=True)
        n[1:-1, 1:-1] = np.where(norm > 0, c / norm, np.nan)
    return n


def test_compiled_normals_equal_the_numpy_formula():
    rng = np.random.default_rng(3)
    K = Intrinsics(40, 30, 35.0, 19.5, 14.5)
    depth = 2.0 + 0.3 * rng.random((30, 40))
    depth[rng.random((30, 40)) < 0.05] = np.nan      # missing pixels make their neighbours' normals NaN
    depth[10:13, 20:23] = np.inf                     # and so do infinite ones (inf − inf)
    V = vertex_map(depth, K)
    V[5, 5:8] = V[5, 6]                              # a vanishing cross product at (5, 6)'s neighbours
    got, want = normal_map(V), normal_map_numpy(V)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    assert np.isnan(got[0]).all() and np.isnan(got[:, -1]).all()
    ok = ~np.isnan(want)
    assert ok[..., 0].mean() > 0.5
    assert np.abs(got[ok] - want[ok]).max() < 1e-12


def test_a_plane_seen_from_the_front_has_its_normal_towards_the_camera():
    K = Intrinsics(8, 6, 5.0, 3.5, 2.5)
    n = normal_map(vertex_map(np.full((6, 8), 2.0), K))
    assert np.allclose(n[1:-1, 1:-1], [0.0, 0.0, -1.0])
