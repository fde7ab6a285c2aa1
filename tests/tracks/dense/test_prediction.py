"""The model rendered into the view (``tracks.dense.prediction``): the splat equals a brute-force
z-buffer (the most confident point within the band of the nearest, nearest-wins among equals of
one surface layer), and ICP against it touches at most one source point a pixel whatever the map's size."""

from __future__ import annotations

import dense_world as dw
import numpy as np
from dense_synthetic import ROOM, perturb, pose_error, render, room_frame, source_set

from assocbench.associators.dense.projective import ProjectiveAssociator
from assocbench.models.camera import Intrinsics
from assocbench.tracks.dense.fusion import PointMap, fuse
from assocbench.tracks.dense.icp import icp
from assocbench.tracks.dense.prediction import Splatter, predict
from assocbench.tracks.dense.run import view_source
from assocbench.tracks.dense.settings import FusionConfig


def camera_point(p, R, t) -> tuple[float, float, float]:
    """``Rᵀ (p − t)`` term by term, in the kernel's order (a BLAS product may round rows differently)."""
    d = [float(p[a] - t[a]) for a in range(3)]
    return tuple(sum(float(R[a, c]) * d[a] for a in range(3)) for c in range(3))


def brute_force(points: np.ndarray, weights: np.ndarray, K, R: np.ndarray, t: np.ndarray, band: float) -> np.ndarray:
    """(H, W) index each pixel shows, by the rule itself with no shared code: per pixel, the list of
    points landing on it; of those within ``band`` of the nearest, the highest weight, then the lowest index."""
    landing: dict = {}
    for i, p in enumerate(points):
        x, y, z = camera_point(p, R, t)
        if not z > 0:
            continue
        u, v = int(np.floor(K.f * x / z + K.cx + 0.5)), int(np.floor(K.f * y / z + K.cy + 0.5))
        if 0 <= u < K.width and 0 <= v < K.height:
            landing.setdefault((v, u), []).append((z, i))
    index = np.full((K.height, K.width), -1)
    for (v, u), hits in landing.items():
        nearest = min(z for z, _ in hits)
        index[v, u] = min((-weights[i], i) for z, i in hits if z <= nearest + band)[1]
    return index


def test_the_splat_equals_a_brute_force_z_buffer():
    frame = room_frame()
    K = frame.K.__class__(40, 30, frame.K.f / 8, frame.K.cx / 8, frame.K.cy / 8)   # a small image: brute force is slow
    rng = np.random.default_rng(3)
    pts = source_set(frame)[0][::37]
    ray = pts - frame.t
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    # the surface, a layer 2 cm behind it (in the band), one 20 cm in front (nearest: it hides both),
    # exact duplicates (equal weight and depth: the lower index), points behind the camera
    cloud = np.concatenate([pts, pts + 0.02 * ray, pts - 0.2 * ray, pts, frame.t - ray])
    weights = rng.integers(1, 4, len(cloud)).astype(float)
    order = rng.permutation(len(cloud))
    cloud, weights = cloud[order], weights[order]
    keep = rng.random(len(cloud)) < 0.7        # the front layer covers only part of the pixels
    front = np.isin(order, np.arange(2 * len(pts), 3 * len(pts)))
    cloud, weights = cloud[keep | ~front], weights[keep | ~front]
    got = predict(cloud, weights, K, frame.R, frame.t, band=0.05)
    want = brute_force(cloud, weights, K, frame.R, frame.t, band=0.05)
    np.testing.assert_array_equal(got.index, want)
    assert (want >= 0).sum() > 300      # the test covers a real view, not an empty image
    z = np.array([camera_point(p, frame.R, frame.t)[2] for p in cloud])
    shown = want >= 0
    np.testing.assert_array_equal(got.depth[shown], z[want[shown]])
    assert np.all(np.isinf(got.depth[~shown]))
    np.testing.assert_array_equal(got.source, want[shown])          # raster order


def test_a_noisier_nearer_duplicate_does_not_win_over_a_merged_point():
    """Of two points of one surface on one pixel, the merged one (weight 5) is shown, not the nearer
    unmerged one: nearest-wins would pick whichever noise pulled towards the camera."""
    K = Intrinsics(4, 3, 3.0, 1.5, 1.0)
    cloud = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 1.99], [0.0, 0.0, 1.5]])
    assert predict(cloud[:2], np.array([5.0, 1.0]), K, np.eye(3), np.zeros(3)).index[1, 2] == 0
    assert predict(cloud[:2], np.array([1.0, 1.0]), K, np.eye(3), np.zeros(3)).index[1, 2] == 0   # tie: lower index
    assert predict(cloud, np.array([5.0, 1.0, 1.0]), K, np.eye(3), np.zeros(3)).index[1, 2] == 2  # 50 cm nearer: hides


def test_a_reused_splatter_forgets_the_previous_frame():
    frame = room_frame()
    pts = source_set(frame)[0]
    w = np.ones(len(pts))
    splat = Splatter(frame.K)
    first = splat.predict(pts, w, frame.R, frame.t).index
    splat.predict(pts[:10], w[:10], frame.R, frame.t)
    np.testing.assert_array_equal(splat.predict(pts, w, frame.R, frame.t).index, first)


class CountingAssociator(ProjectiveAssociator):
    """The projective method, recording how many source points each call is handed."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.handed: list[int] = []

    def associate(self, points, normals, frame, R, t):
        self.handed.append(len(points))
        return super().associate(points, normals, frame, R, t)


def test_icp_against_the_view_touches_at_most_a_point_a_pixel_whatever_the_map_size():
    """The work of every ICP iteration (the points handed to the association) is bounded by the pixel
    count, and a map ten times larger (its extra points hidden behind the surface or outside the view)
    hands ICP exactly the same points and gives the same pose."""
    A = room_frame()
    pts, nrm, tp, geom = source_set(A)
    small = PointMap.from_arrays(pts, nrm, true_points=tp, geom=geom)
    rng = np.random.default_rng(5)
    behind = pts + (0.2 + rng.random((len(pts), 1))) * (pts - A.t)    # hidden behind the surface
    outside = pts + np.array([0.0, 0.0, -30.0])                        # far below the floor, out of view
    big = PointMap.from_arrays(np.concatenate([pts] + [behind] * 5 + [outside] * 4),
                               np.concatenate([nrm] * 10), true_points=np.concatenate([tp] * 10),
                               geom=np.concatenate([geom] * 10))
    assert len(big) == 10 * len(small)
    RB, tB = perturb(A.R, A.t, 1.0, 0.02, np.random.default_rng(7))
    B = render(ROOM, RB, tB)
    runs = []
    for pmap in (small, big):
        source = view_source(pmap, Splatter(A.K), A.R, A.t)
        assoc = CountingAssociator()
        res = icp(source.points, source.normals, B, assoc, A.R, A.t)
        runs.append((assoc.handed, res))
    pixels = A.K.width * A.K.height
    (handed_small, res_small), (handed_big, res_big) = runs
    assert len(handed_big) > 2 and max(handed_big) <= pixels
    assert handed_big == handed_small
    np.testing.assert_array_equal(res_big.R, res_small.R)
    err_m, err_deg = pose_error(res_big.R, res_big.t, RB, tB)
    assert not res_big.failed and err_m < 1e-3 and err_deg < 0.05


def test_shown_rows_are_the_predictions_source_without_its_maps():
    """Frame-to-model tracking reads only the shown points and the visited count: the lighter call
    gives exactly the prediction's."""
    _, _, frames = dw.sequence(4, yaw_per_frame=4.0)
    pmap = PointMap()
    for k, f in enumerate(frames[:3]):
        fuse(pmap, f, f.R, f.t, k, FusionConfig())
    splat, f = Splatter(dw.K320), frames[3]
    for index in (True, False):
        rows, scanned = splat.shown_rows(pmap, f.R, f.t, index)
        full = splat.predict_map(pmap, f.R, f.t, index)
        np.testing.assert_array_equal(rows, full.source)
        assert scanned == full.scanned and len(rows) > 1000
