"""The map's rows in spatial order (``tracks.dense.map_order``): sorting changes no number of a run,
only which rows share a block, and the sorted map's table and blocks stay true."""

from __future__ import annotations

import dense_world as dw
import numpy as np
import pytest

from assocbench.tracks.dense.fusion import BLOCK, PointMap, fuse, warm_fusion
from assocbench.tracks.dense.map_order import CELL, morton_keys
from assocbench.tracks.dense.prediction import Splatter
from assocbench.tracks.dense.settings import FusionConfig
from assocbench.tracks.dense.voxel_table import table_find

FIELDS = ("positions", "normals", "weights", "last_seen", "true_points", "geom", "born")
SAME = ("merged", "added", "removed", "dormant", "outliers", "considered", "mixed", "size", "binned", "dropped")


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    warm_fusion()


def by_birth(pmap: PointMap) -> dict[str, np.ndarray]:
    order = np.argsort(pmap.born)
    return {name: getattr(pmap, name)[order] for name in FIELDS}


@pytest.mark.parametrize("voxel", [0.01, 0.0])
def test_sorting_after_every_frame_changes_no_statistic_point_or_prediction(voxel):
    """Noisy frames of a turning camera (points turn dormant and are seen through, so rows are
    removed and moved): a map sorted after every fusion and one never sorted hold the same points
    with the same fields, report the same statistics and show the same points on every pixel."""
    _, _, frames = dw.sequence(14, yaw_per_frame=6.0)
    cfg = FusionConfig(dormant_frames=3, voxel=voxel)
    plain, sorted_ = PointMap(), PointMap()
    plain.sort_share, sorted_.sort_share = None, 0.0
    splat = Splatter(dw.K320)
    removed = 0
    for k, f in enumerate(frames):
        a = splat.predict_map(plain, f.R, f.t)
        b = splat.predict_map(sorted_, f.R, f.t)
        np.testing.assert_array_equal(np.where(a.index >= 0, plain._born[a.index], -1),
                                      np.where(b.index >= 0, sorted_._born[b.index], -1))
        np.testing.assert_array_equal(a.depth, b.depth)
        sa, sb = fuse(plain, f, f.R, f.t, k, cfg), fuse(sorted_, f, f.R, f.t, k, cfg)
        assert [getattr(sa, s) for s in SAME] == [getattr(sb, s) for s in SAME]
        removed += sa.removed
        ref, got = by_birth(plain), by_birth(sorted_)
        for name in FIELDS:
            np.testing.assert_array_equal(got[name], ref[name], err_msg=name)
    assert removed > 0 and not np.array_equal(plain.born, sorted_.born)   # rows moved, and the orders differ
    assert np.array_equal(sorted_.copy().born, sorted_.born)


def test_a_sorted_map_runs_in_cell_order_with_its_table_and_boxes_true():
    _, _, frames = dw.sequence(6, yaw_per_frame=6.0)
    pmap, cfg = PointMap(), FusionConfig()
    pmap.sort_share = None
    for k, f in enumerate(frames):
        fuse(pmap, f, f.R, f.t, k, cfg)
    pmap.sort_spatially()
    n = len(pmap)
    keys = morton_keys(pmap._pos, n, 1.0 / CELL)
    assert np.all(keys[1:] >= keys[:-1])
    rows = [table_find(pmap._table_keys, pmap._table_rows, pmap._key[i]) for i in range(n) if pmap._key[i] >= 0]
    assert rows == [i for i in range(n) if pmap._key[i] >= 0]
    for b in range(-(-n // BLOCK)):
        block = pmap.positions[b * BLOCK:(b + 1) * BLOCK]
        np.testing.assert_array_equal(pmap._lo[b], block.min(axis=0))
        np.testing.assert_array_equal(pmap._hi[b], block.max(axis=0))


def test_morton_order_keeps_neighbouring_cells_near_and_nan_last():
    step = CELL * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [2, 0, 0], [np.nan, 0, 0]])
    keys = morton_keys(step + 0.5 * CELL, len(step), 1.0 / CELL)
    assert list(np.argsort(keys, kind="stable")) == [0, 1, 2, 3, 4, 5, 6]
    assert keys[-1] == np.iinfo(np.int64).max
