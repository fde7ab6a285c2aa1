"""The map's index (``tracks.dense.fusion``: blocks of points with bounding boxes): fusion and the
splat that visit only the blocks in view give the whole-map result bit for bit, and the points they
visit per frame follow what is in view, not the map's size."""

from __future__ import annotations

import dense_world as dw
import numpy as np
import pytest

from assocbench.tracks.dense.fusion import BLOCK, PointMap, frustum_blocks, fuse, warm_fusion
from assocbench.tracks.dense.prediction import Splatter
from assocbench.tracks.dense.settings import FusionConfig

FIELDS = ("positions", "normals", "weights", "last_seen", "true_points", "geom")


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    warm_fusion()


def assert_same_map(a: PointMap, b: PointMap) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_indexed_fusion_and_splat_equal_the_whole_map_pass():
    """A camera turning away (the map's first walls leave the view), noisy frames so that points go
    dormant and are seen through; every statistic, every map row in its order and every prediction
    agree with ``index=False``."""
    _, _, frames = dw.sequence(14, yaw_per_frame=6.0)
    cfg = FusionConfig(dormant_frames=3, voxel=0)   # a point a pixel: the map outgrows the view
    indexed, whole = PointMap(), PointMap()
    splat = Splatter(dw.K320)
    skipped = 0
    for k, f in enumerate(frames):
        a = splat.predict_map(indexed, f.R, f.t)
        b = splat.predict_map(whole, f.R, f.t, index=False)
        np.testing.assert_array_equal(a.index, b.index)
        np.testing.assert_array_equal(a.depth, b.depth)
        assert a.landed == b.landed and a.scanned <= b.scanned == len(whole)
        sa, sb = fuse(indexed, f, f.R, f.t, k, cfg), fuse(whole, f, f.R, f.t, k, cfg, index=False)
        assert sa.scanned <= sb.scanned
        skipped += sb.scanned - sa.scanned
        assert (sa.merged, sa.added, sa.removed, sa.dormant, sa.outliers, sa.considered, sa.mixed, sa.size) == \
            (sb.merged, sb.added, sb.removed, sb.dormant, sb.outliers, sb.considered, sb.mixed, sb.size)
        assert_same_map(indexed, whole)
    assert skipped > 0                        # the index did skip work: the test compares two different paths


def test_work_per_frame_follows_the_view_not_the_map():
    """A map ten times the view's points, nine tenths of them far outside the view (and stable, so
    never dormant): the splat and the fusion visit about the view's points, the whole-map pass all."""
    model, data = dw.world()
    f = dw.frame(model, data, *dw.pose(0), None)
    cfg = FusionConfig(stable_weight=1, voxel=0)   # every point stable: none visited for the dormant rule
    pmap = PointMap()
    fuse(pmap, f, f.R, f.t, 0, cfg)
    seen = len(pmap)
    away = pmap.positions + np.array([0.0, 0.0, -50.0])   # far below the floor
    big = PointMap.from_arrays(np.concatenate([pmap.positions] + [away] * 9),
                               np.concatenate([pmap.normals] * 10), weights=5.0)
    pred = Splatter(dw.K320).predict_map(big, f.R, f.t)
    assert pred.scanned <= seen + BLOCK and pred.landed == seen
    st = fuse(big, f, f.R, f.t, 1, cfg)
    assert st.scanned <= seen + BLOCK and st.merged == seen
    assert fuse(big.copy(), f, f.R, f.t, 1, cfg, index=False).scanned == len(big)


def test_a_box_is_culled_only_when_wholly_outside_the_frustum():
    """Boxes around single points: one inside the image, one behind the camera, one beside the view,
    and one on the image's edge ray (kept: the margin never culls a point that lands)."""
    K = dw.K320
    R, t = np.eye(3), np.zeros(3)
    z = 2.0
    edge_x = (0 - K.cx - 0.5) / K.f * z          # u = f x/z + cx + ½ = 0 exactly: lands on column 0
    pts = np.array([[0.0, 0.0, z], [0.0, 0.0, -z], [10.0 * z, 0.0, z], [edge_x, 0.0, z]])
    got = frustum_blocks(pts.copy(), pts.copy(), 4, R, t, float(K.f), float(K.cx), float(K.cy), K.width, K.height)
    np.testing.assert_array_equal(got, [0, 3])
