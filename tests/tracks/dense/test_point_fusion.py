"""Point-based fusion (the dense homework's section 3 and bonus) on synthetic depth frames of a room
corner (``dense_world``): the merge formulas, accuracy and size of a fused static scene, addition,
dormant and outlier removal, the truth carried along, the numpy reference, and bad settings."""

import dense_world as dw
import numpy as np
import pytest
from fusion_reference import NumpyMap, fuse_numpy

from assocbench.errors import UserError
from assocbench.models.camera import Intrinsics
from assocbench.models.depth_frame import NO_GEOM, DepthFrame, normal_map, vertex_map
from assocbench.tracks.dense.fusion import MIXED_GEOM, PointMap, compression_ratio, fuse, warm_fusion
from assocbench.tracks.dense.settings import FusionConfig
from assocbench.tracks.dense.surface import surface_distance

PLANES = ("floor", "back", "left", "new")


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    warm_fusion()


def empty_frame(K: Intrinsics = dw.K320) -> DepthFrame:
    """A frame that sees nothing (the camera looking at the sky)."""
    nan = np.full((K.height, K.width), np.nan)
    V = vertex_map(nan, K)
    return DepthFrame(K, nan, V, V.copy(), V.copy(), np.full(nan.shape, NO_GEOM), np.eye(3), np.zeros(3))


def test_merge_is_the_homeworks_weighted_average():
    # a tilted plane seen by a 6x5 camera; pose: 90° about z (exact entries) and a dyadic shift
    K = Intrinsics(6, 5, 2.0, 2.5, 2.0)
    depth = 2.0 + 0.25 * np.arange(6)[None, :] + 0.5 * np.arange(5)[:, None]
    V = vertex_map(depth, K)
    N = normal_map(V)
    frame = DepthFrame(K, depth, V, N, V + 10.0, np.full((5, 6), 7), np.eye(3), np.zeros(3))
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = np.array([0.5, -0.25, 1.0])
    pix = [(1, 2), (2, 3)]                       # (v, u): two map points, weights 3 and 1
    q = np.array([R @ V[v, u] + t for v, u in pix])
    nq = np.array([R @ N[v, u] for v, u in pix])
    p = q + np.array([[0.01, -0.02, 0.005], [-0.015, 0.0, 0.02]])
    n_p = nq + np.array([[0.1, 0.0, -0.05], [0.0, 0.08, 0.0]])
    n_p /= np.linalg.norm(n_p, axis=1, keepdims=True)
    w = np.array([3.0, 1.0])
    tp = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    pmap = PointMap.from_arrays(p, n_p, w, 0, tp, 7)
    pmap.sort_share = None   # rows stay where they are (sorting moves rows only: test_map_order.py)
    st = fuse(pmap, frame, R, t, 1, FusionConfig(angle_deg=30))
    assert (st.merged, st.added, st.removed) == (2, 12 - 2, 0)   # 12 valid pixels (a normal needs all 4 neighbours)
    want_p = (w[:, None] * p + q) / (w[:, None] + 1)                # p <- (w p + R q + t) / (w + 1)
    want_n = (w[:, None] * n_p + nq) / (w[:, None] + 1)             # n <- (w n + R n_q) / (w + 1), normalised
    want_n /= np.linalg.norm(want_n, axis=1, keepdims=True)
    want_tp = (w[:, None] * tp + np.array([V[v, u] + 10.0 for v, u in pix])) / (w[:, None] + 1)
    np.testing.assert_array_equal(pmap.positions[:2], want_p)
    np.testing.assert_allclose(pmap.normals[:2], want_n, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(pmap.true_points[:2], want_tp)
    np.testing.assert_array_equal(pmap.weights[:2], w + 1)
    np.testing.assert_array_equal(pmap.last_seen, 1)
    np.testing.assert_array_equal(pmap.geom, 7)
    # the 10 pixels no map point took are added as R q + t, R n_q, weight 1
    rest = [(v, u) for v in range(1, 4) for u in range(1, 5) if (v, u) not in pix]
    np.testing.assert_array_equal(pmap.positions[2:], [R @ V[v, u] + t for v, u in rest])
    np.testing.assert_array_equal(pmap.weights[2:], 1.0)


def test_compiled_kernels_match_the_numpy_reference():
    model, data, frames = dw.sequence(10, yaw_per_frame=2.0)
    for cfg in (FusionConfig(voxel=0), FusionConfig(angle_deg=90, dormant_frames=3, voxel=0)):
        pmap = PointMap()
        pmap.sort_share = None   # the reference keeps the homework's row order (sorting: test_map_order.py)
        ref = NumpyMap.of(pmap)
        for k, f in enumerate(frames):
            st = fuse(pmap, f, f.R, f.t, k, cfg)
            assert (st.merged, st.added, st.removed) == fuse_numpy(ref, f, f.R, f.t, k, cfg)
        for name in ("positions", "normals", "true_points"):
            np.testing.assert_allclose(getattr(pmap, name), getattr(ref, name), rtol=0, atol=1e-12)
        for name in ("weights", "last_seen", "geom"):
            np.testing.assert_array_equal(getattr(pmap, name), getattr(ref, name))


@pytest.mark.parametrize("smooth, angle", [(True, 20.0), (False, 180.0)])
def test_fused_static_scene_beats_one_frame_and_grows_sublinearly(smooth, angle):
    # 30 noisy frames (σ = 5.6 mm at 1.5 m, 15 mm at 2.7 m) of the room corner from poses a few cm
    # apart, true poses. Smoothed normals at the default 20° gate; or the raw neighbour-difference
    # normals (median error 58° at these depths) with the normal gate off: see the report.
    model, data, frames = dw.sequence(30, smooth=smooth)
    f0 = frames[0]
    single = surface_distance(f0.vertices[f0.valid] @ f0.R.T + f0.t, model)
    pmap, sizes = PointMap(), []
    for k, f in enumerate(frames):
        fuse(pmap, f, f.R, f.t, k, FusionConfig(angle_deg=angle, voxel=0))   # the homework's rule
        sizes.append(len(pmap))
    err = surface_distance(pmap.positions, model)
    # measured: single frame median 5.6 mm (p95 24 mm); map median 1.2-1.3 mm (p95 5.8-6.1 mm)
    assert np.median(single) == pytest.approx(5.6e-3, abs=0.3e-3)
    assert np.median(err) < 0.3 * np.median(single)
    assert np.percentile(err, 95) < 0.35 * np.percentile(single, 95)
    # sublinear: frames 21-30 add under half of what frames 2-10 add; the map holds 1.5 frames' pixels
    assert sizes[29] - sizes[19] < 0.5 * (sizes[9] - sizes[0])
    assert sizes[29] < 1.6 * f0.valid.sum()
    ratio = compression_ratio(sizes[29], 30, 320, 240)
    assert ratio < 0.055   # measured 0.049 of the 320x240 frames fused


def test_a_wall_coming_into_view_adds_its_pixels():
    model, data = dw.world()
    new = dw.geom_id(model, "new")
    a = dw.frame(model, data, *dw.pose(0), np.random.default_rng([1, 0, 17]), smooth=True)
    b = dw.frame(model, data, *dw.pose(1, yaw_deg=40.0), np.random.default_rng([1, 1, 17]), smooth=True)
    assert not (a.geom == new).any() and (b.valid & (b.geom == new)).sum() > 5000
    pmap, homework = PointMap(), FusionConfig(voxel=0)   # every unmerged pixel added
    fuse(pmap, a, a.R, a.t, 0, homework)
    before = len(pmap)
    st = fuse(pmap, b, b.R, b.t, 1, homework)
    seen = (b.valid & (b.geom == new)).sum()
    on_new = pmap.geom == new
    assert st.merged > 10000 and st.added >= seen and len(pmap) == before + st.added - st.removed
    assert on_new.sum() == seen   # every valid pixel of the new wall became a point, none merged elsewhere
    assert np.median(surface_distance(pmap.positions[on_new], model, [new])) < 0.02


def test_dormant_unstable_points_go_after_dormant_frames_and_stable_ones_stay():
    model, data = dw.world()
    a = [dw.frame(model, data, *dw.pose(0), None) for _ in range(3)]       # noise-free: each merges fully
    b = dw.frame(model, data, *dw.pose(1, yaw_deg=40.0), None)
    cfg = FusionConfig(dormant_frames=4, stable_weight=3, voxel=0)
    pmap = PointMap()
    for k, f in enumerate(a):
        fuse(pmap, f, f.R, f.t, k, cfg)
    stable = len(pmap)
    assert np.all(pmap.weights == 3)
    st = fuse(pmap, b, b.R, b.t, 3, cfg)        # the new wall and more: weight-1 points, last seen at 3
    fresh = st.added
    assert fresh > 5000 and st.removed == 0
    sky = empty_frame()
    for k in range(4, 3 + 4):                   # frames 4, 5, 6: not yet dormant_frames without a merge
        st = fuse(pmap, sky, np.eye(3), np.zeros(3), k, cfg)
        assert (st.merged, st.added, st.removed) == (0, 0, 0) and len(pmap) == stable + fresh
    st = fuse(pmap, sky, np.eye(3), np.zeros(3), 7, cfg)   # k − last_seen = 4: the unstable ones go
    assert st.dormant == st.removed == fresh and len(pmap) == stable
    assert np.all(pmap.weights >= 3)
    st = fuse(pmap, sky, np.eye(3), np.zeros(3), 500, cfg)
    assert st.removed == 0 and len(pmap) == stable


def floaters(pmap: PointMap, frame: DepthFrame, share: float, rows: slice) -> tuple[np.ndarray, np.ndarray]:
    """Points at ``share`` of the way from the camera to some map points on the back wall, facing the camera."""
    pts = pmap.positions[rows]
    return frame.t + share * (pts - frame.t), pmap.normals[rows]


def test_outliers_the_sensor_sees_through_are_removed_unless_stable():
    model, data = dw.world()
    f = dw.frame(model, data, *dw.pose(0), None)
    wall = PointMap()
    for k in range(3):
        fuse(wall, f, f.R, f.t, k, FusionConfig(voxel=0))   # a stable wall map (weight 3), a point a pixel
    back = np.flatnonzero(wall.geom == dw.geom_id(model, "back"))
    front, nf = floaters(wall, f, 0.8, back[:50])        # 0.5 m in front of the wall: seen through
    behind, nb = floaters(wall, f, 1.2, back[50:80])     # behind it: hidden, not contradicted
    stable, ns = floaters(wall, f, 0.8, back[80:90])
    pos = np.concatenate([wall.positions, front, behind, stable])
    nrm = np.concatenate([wall.normals, nf, nb, ns])
    w = np.concatenate([wall.weights, np.ones(80), np.full(10, 5.0)])
    geom = np.concatenate([wall.geom, np.full(90, 99)])
    for drop in (True, False):
        pmap = PointMap.from_arrays(pos, nrm, w, 2, None, geom)
        st = fuse(pmap, f, f.R, f.t, 3, FusionConfig(remove_outliers=drop, voxel=0))
        assert st.outliers == st.removed == (50 if drop else 0)
        assert (pmap.geom == 99).sum() == (40 if drop else 90)
        assert ((pmap.geom == 99) & (pmap.weights == 1)).sum() == (30 if drop else 80)   # the 30 behind stay


def test_truth_moves_with_its_point_through_merge_add_and_remove():
    # noise-free frames: every vertex is its true point, so position == true point must hold for every
    # map point after any mix of merges, additions and removals (hole filling moves rows)
    model, data, frames = dw.sequence(16, noise=False, yaw_per_frame=3.0, step=0.02)
    pmap, total = PointMap(), np.zeros(3, int)
    for k, f in enumerate(frames):
        st = fuse(pmap, f, f.R, f.t, k, FusionConfig(dormant_frames=2, stable_weight=4, voxel=0))
        total += (st.merged, st.added, st.removed)
    assert total.min() > 10000, total
    np.testing.assert_allclose(pmap.positions, pmap.true_points, rtol=0, atol=1e-9)
    planes = [dw.geom_id(model, name) for name in PLANES]
    assert sum((pmap.geom == g).sum() > 1000 for g in planes) >= 3   # the left wall left the view
    for g in planes:                            # a plane's averaged true points stay on it
        on = pmap.geom == g
        assert surface_distance(pmap.true_points[on], model, [g]).max(initial=0.0) < 1e-9
    crate = dw.geom_id(model, "crate")          # averaged across a box edge: inside, near the surface
    assert surface_distance(pmap.true_points[pmap.geom == crate], model, [crate]).max() < 0.02
    assert set(np.unique(pmap.geom)) <= {MIXED_GEOM, *range(model.ngeom)}


def test_noisy_truth_stays_with_its_point():
    model, data, frames = dw.sequence(12, smooth=True, yaw_per_frame=2.0)
    pmap = PointMap()
    for k, f in enumerate(frames):
        fuse(pmap, f, f.R, f.t, k, FusionConfig(dormant_frames=3))
    gap = np.linalg.norm(pmap.positions - pmap.true_points, axis=1)
    assert np.median(gap) < 0.01 and np.percentile(gap, 99) < 0.05   # within noise, never another point's truth
    assert np.mean(pmap.geom == MIXED_GEOM) < 0.02   # a cell on a crate's edge averages two geoms (1.7 % at 2 cm)


def test_empty_frame_changes_nothing_but_time():
    pmap = PointMap()
    st = fuse(pmap, empty_frame(), np.eye(3), np.zeros(3), 0)
    assert (st.merged, st.added, st.removed, len(pmap)) == (0, 0, 0, 0)


def test_compression_ratio_is_the_homeworks_definition():
    # the homework's 8.87 % counts its fused 320x240 frames (640x480 downsampled by 2)
    assert compression_ratio(1_362_143, 200, 320, 240) == pytest.approx(0.0887, abs=5e-5)
    assert compression_ratio(1_362_143, 200, 640, 480) == pytest.approx(0.0887 / 4, abs=5e-5)
    with pytest.raises(UserError, match="frames"):
        compression_ratio(10, 0, 640, 480)


@pytest.mark.parametrize("field, value, message", [
    ("d_thr", 0.0, "fusion.d_thr must be a finite number in \\(0"),
    ("d_thr", -0.1, "fusion.d_thr"),
    ("d_thr", float("nan"), "fusion.d_thr"),
    ("angle_deg", 0.0, "fusion.angle_deg"),
    ("angle_deg", 181.0, "fusion.angle_deg"),
    ("dormant_frames", 0, "fusion.dormant_frames must be an integer"),
    ("dormant_frames", 2.5, "fusion.dormant_frames must be an integer"),
    ("stable_weight", 0, "fusion.stable_weight"),
    ("remove_outliers", "yes", "fusion.remove_outliers must be true or false"),
])
def test_bad_settings_are_one_line_errors(field, value, message):
    with pytest.raises(UserError, match=message) as err:
        FusionConfig(**{field: value})
    assert "\n" not in str(err.value)


def test_bad_pose_and_frame_index_are_one_line_errors():
    f = empty_frame()
    for R, t, k, message in [(np.diag([1.0, 1.0, 2.0]), np.zeros(3), 0, "not a rotation"),
                             (np.diag([1.0, 1.0, -1.0]), np.zeros(3), 0, "not a rotation"),
                             (np.eye(3), np.zeros(2), 0, "3x3 rotation R and 3-vector t"),
                             (np.eye(3), np.array([0, np.nan, 0]), 0, "finite"),
                             (np.eye(3), np.zeros(3), -1, "frame index k"),
                             (np.eye(3), np.zeros(3), 1.5, "frame index k")]:
        with pytest.raises(UserError, match=message) as err:
            fuse(PointMap(), f, R, t, k)
        assert "\n" not in str(err.value)


def _cell(q: np.ndarray, m: np.ndarray, size: float, thick: float) -> tuple:
    """The voxel table's cell of a point: ``thick`` along the normal's dominant axis, ``size`` along
    the others (multiplied by the inverse, as the kernel does), and that axis with its sign."""
    a = int(np.argmax(np.abs(m)))
    scale = np.where(np.arange(3) == a, 1.0 / thick, 1.0 / size)
    return (*np.floor(q * scale).astype(int), 2 * a + int(m[a] < 0))


def test_a_pixel_in_a_held_cell_merges_into_its_point_and_a_frame_counts_once():
    # a fronto-parallel plane at 2 m, 0.1 m a pixel; the one map point (weight 2) projects onto the
    # missing pixel (2, 3), so nothing merges projectively and every pixel goes through the cells (0.2 m)
    K = Intrinsics(6, 5, 20.0, 2.5, 2.0)
    depth = np.full((5, 6), 2.0)
    depth[2, 3] = np.nan
    V = vertex_map(depth, K)
    N = np.where(np.isnan(V), np.nan, np.array([0.0, 0.0, -1.0]))
    frame = DepthFrame(K, depth, V, N, V.copy(), np.full((5, 6), 4), np.eye(3), np.zeros(3))
    p0, n0 = np.array([0.02, 0.0, 2.0]), np.array([0.0, 0.0, -1.0])
    pmap = PointMap.from_arrays(p0[None], n0[None], 2.0, 0, p0[None], 4)
    pmap.sort_share = None   # row 0 stays the held point (sorting moves rows only: test_map_order.py)
    st = fuse(pmap, frame, np.eye(3), np.zeros(3), 1, FusionConfig(voxel=0.2))
    # the reference: each cell's samples of this frame averaged, then the homework's merge with weight 1
    # (the cell's neighbours along the normal, z here, are empty: the plane lies in one layer)
    cells = {}
    for v in range(5):
        for u in range(6):
            if not np.isnan(depth[v, u]):
                cells.setdefault(_cell(V[v, u], N[v, u], 0.2, 0.2), []).append(V[v, u])
    held = _cell(p0, n0, 0.2, 0.2)
    want = (2.0 * p0 + np.mean(cells[held], axis=0)) / 3.0
    new = [np.mean(c, axis=0) for key, c in cells.items() if key != held]
    assert (st.merged, st.added, st.dropped) == (0, len(new), 0)
    assert st.binned == sum(len(c) for c in cells.values()) - len(new)
    np.testing.assert_allclose(pmap.positions[0], want, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(pmap.weights, [3.0] + [1.0] * len(new))
    got = sorted(map(tuple, np.round(pmap.positions[1:], 9)))
    np.testing.assert_allclose(got, sorted(map(tuple, np.round(new, 9))), rtol=0, atol=1e-15)
    np.testing.assert_allclose(pmap.true_points, pmap.positions, rtol=0, atol=1e-15)   # truth averaged alike
    assert len(new) >= 4 and max(len(c) for c in cells.values()) >= 2


def test_cells_bound_the_map_where_the_homework_rule_grows():
    # the room corner from 30 poses a few cm apart (true poses): the homework's rule adds the pixels
    # between the old points at every new pose, one point per cell grows slower, as accurate
    model, data, frames = dw.sequence(30, smooth=True)
    f0 = frames[0]
    single = surface_distance(f0.vertices[f0.valid] @ f0.R.T + f0.t, model)
    sizes, maps = {}, {}
    for voxel in (0.0, 0.01):
        pmap, sizes[voxel] = PointMap(), []
        for k, f in enumerate(frames):
            fuse(pmap, f, f.R, f.t, k, FusionConfig(voxel=voxel))
            sizes[voxel].append(len(pmap))
        maps[voxel] = pmap
    grown = {v: s[29] - s[19] for v, s in sizes.items()}
    # measured: 3 806 against 5 974 added by frames 21-30 (1 cm cells are about this camera's pixel
    # footprint at 1.5-2.7 m, so they fill slowly); the map 0.74 of the homework's
    assert grown[0.01] < 0.7 * grown[0.0] and sizes[0.01][29] < 0.8 * sizes[0.0][29], (grown, sizes)
    cells = maps[0.01]._key[:len(maps[0.01])]
    assert len(np.unique(cells)) == len(cells) and (cells >= 0).all()   # one point per cell
    err = {v: surface_distance(m.positions, model) for v, m in maps.items()}
    assert np.median(err[0.01]) < 0.3 * np.median(single)
    assert np.median(err[0.01]) < 1.3 * np.median(err[0.0])


def test_removal_keeps_the_cells_of_the_moved_points():
    # dormant removal fills holes with rows from the end: the table must follow (a stale row would merge
    # a pixel into another cell's point); afterwards every point is found under its own key
    from assocbench.tracks.dense.voxel_table import table_find

    model, data, frames = dw.sequence(12, smooth=True, yaw_per_frame=3.0)
    pmap, removed = PointMap(), 0
    for k, f in enumerate(frames):
        removed += fuse(pmap, f, f.R, f.t, k, FusionConfig(dormant_frames=2, stable_weight=4)).removed
    assert removed > 1000
    rows = [table_find(pmap._table_keys, pmap._table_rows, key) for key in pmap._key[:len(pmap)]]
    np.testing.assert_array_equal(rows, np.arange(len(pmap)))


def test_the_voxel_table_is_never_more_than_half_full():
    """Linear probing ends at an EMPTY slot; the table (2x the keys since it stopped being 4x) keeps
    at least half its slots EMPTY after every frame: with tombstones (dormant removal), after the
    rebuilds a 320x240 frame forces on an empty map, and on a copy (``from_arrays``: keyed afresh),
    and ``_table_used`` counts exactly the slots not EMPTY."""
    from assocbench.tracks.dense.voxel_table import EMPTY, GONE

    _, _, frames = dw.sequence(12, smooth=True, yaw_per_frame=3.0)
    cfg = FusionConfig(dormant_frames=2, stable_weight=4)
    pmap, tombstones = PointMap(), 0
    for k, f in enumerate(frames):
        if k == 6:
            pmap = pmap.copy()
        fuse(pmap, f, f.R, f.t, k, cfg)
        keys = pmap._table_keys
        assert (keys != EMPTY).sum() == pmap._table_used and 2 * pmap._table_used <= len(keys), k
        tombstones = max(tombstones, int((keys == GONE).sum()))
    assert tombstones > 0   # the removals left some: they count as used
    # the worst case the size is for: 1 mm cells, nearly every pixel of a 320x240 frame adds its own key
    first = PointMap()
    added = fuse(first, frames[0], frames[0].R, frames[0].t, 0, FusionConfig(voxel=0.001)).added
    assert added > 0.85 * 320 * 240 and added == first._table_used <= len(first._table_keys) // 2


def test_a_slot_key_and_row_share_a_cache_line_through_rebuilds_and_copies():
    """The cell pass probes a table of megabytes at random: a found key's row must lie beside it (a
    second array was a second cache miss). Every table a map holds, its first, the one rebuilt for
    a frame's keys and a copy's, is one (size, 2) array."""
    from assocbench.tracks.dense.voxel_table import EMPTY, new_table, table_find, table_insert

    keys, rows = new_table(8)
    assert keys.base is rows.base and keys.strides == rows.strides == (16,) and (keys == EMPTY).all()
    table_insert(keys, rows, 12345, 7)
    assert table_find(keys, rows, 12345) == 7 and keys.base[:, 0].tolist().count(12345) == 1
    _, _, frames = dw.sequence(4, smooth=True, yaw_per_frame=3.0)
    pmap, sizes = PointMap(), set()
    for k, f in enumerate(frames):
        fuse(pmap, f, f.R, f.t, k)
        for m in (pmap, pmap.copy()):
            assert m._table_keys.base is m._table_rows.base and m._table_keys.strides == (16,), k
            sizes.add(len(m._table_keys))
    assert len(sizes) >= 2   # the first table (a copy's) and one rebuilt for a frame's keys


def test_a_neighbour_cell_takes_a_sample_only_within_half_the_thickness():
    # a floor-like point (normal +z) in the 5 cm layer below z = 2.0; samples just above the layer
    # face join it when they lie within 2.5 cm of it along z, else they start their own cell (a
    # crate's slats 6 cm apart merged across layers and slid frame-to-model tracking 60 mm in z)
    from assocbench.tracks.dense.voxel_table import cell_key, held_cell, new_table, table_insert

    keys, rows = new_table(16)
    inv_size, inv_thick = 100.0, 20.0
    pos = np.array([[0.155, 0.005, 1.985]])
    table_insert(keys, rows, cell_key(*pos[0], 0.0, 0.0, 1.0, inv_size, inv_thick), 0)
    for z, want in ((2.005, 0), (2.012, -1), (1.99, 0)):
        q = (0.155, 0.005, z)
        key = cell_key(*q, 0.0, 0.0, 1.0, inv_size, inv_thick)
        assert held_cell(keys, rows, key, *q, inv_thick, pos, 0.5 / inv_thick) == want, z
