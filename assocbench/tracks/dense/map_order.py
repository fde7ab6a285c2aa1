"""The point map's rows in spatial order, so that its blocks are small boxes.

The map's index (``fusion``: blocks of ``BLOCK`` consecutive rows, each with a bounding box) lets
the splat and fusion's merge pass skip the blocks outside the view frustum. That works only if a
block's points lie close together. Rows are appended as fusion adds them: a frame's new points in
raster order, a few hundred a frame scattered over the image once the scene is seen, and removal
moves the last rows into the holes. Later blocks then span the room, and over a 500-frame crates
path the points visited grew 67k -> 134k while those in view went 64k -> 84k.

So the map is put in spatial order from time to time (``PointMap.sort_spatially``, called by
``fuse`` once the rows added or moved since the last sort pass ``SORT_SHARE`` of the map): all its rows
sorted, stably, by the Morton (z-order) code of their ``CELL`` cell, which keeps nearby cells
near in the order, so a block holds one cell's points or a few neighbouring cells'. Every row
moves with all its fields, and the voxel table is told the new rows. A sort costs 3.5-15 ms
(50k-175k points), about once every 10-25 frames on the crates path.

Measured by ``benchmarks/dense_map_order.py``: the 500-frame crates path fused at true poses with
the splat of each frame, sorted and unsorted maps interleaved frame by frame in one process:
splat and fusion 13.1 -> 19.3 ms a frame from the first to the last hundred frames with the sort
(sorts included), 13.8 -> 22.4 ms without; the points the splat visits 62k -> 101k against 67k ->
134k. Cells of 0.1, 0.2, 0.4 and 0.8 m gave the last hundred frames 0.85-0.88 of the unsorted
time; 0.4 m also left the first hundred no slower (sorted rows visit the image's pixels less in
order than rows appended in raster order, which the smaller cells pay for).

Nothing computed from the map depends on its row order (the splat breaks a tie of weights by
the point's ``born`` serial, not by its row), so sorting changes no number of a run: the maps
with and without it hold the same points with the same fields (tests/tracks/dense/test_map_order.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

CELL = 0.4          # m: the cells the order runs through (measured 0.1-0.8 m, module docstring)
SORT_SHARE = 0.1   # sort once the rows added or moved since the last sort reach this share of the map
_BITS = 21          # bits per axis of the Morton code: 3 x 21 = 63
_OFFSET = 1 << (_BITS - 1)


@njit(cache=True)
def _spread(v):
    """The low 21 bits of ``v`` moved to every third bit (bit k -> bit 3k)."""
    v &= 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    v = (v | (v << 2)) & 0x1249249249249249
    return v


@njit(cache=True)
def morton_keys(pos, n, inv_cell):
    """Morton code of each row's cell ``⌊p / CELL⌋`` (offset by 2^20 per axis; NaN rows last)."""
    out = np.empty(n, np.int64)
    for i in range(n):
        x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
        if not (x == x and y == y and z == z):
            out[i] = np.iinfo(np.int64).max
            continue
        cx = min(max(np.floor(x * inv_cell) + _OFFSET, 0.0), 2.0 * _OFFSET - 1)
        cy = min(max(np.floor(y * inv_cell) + _OFFSET, 0.0), 2.0 * _OFFSET - 1)
        cz = min(max(np.floor(z * inv_cell) + _OFFSET, 0.0), 2.0 * _OFFSET - 1)
        out[i] = _spread(np.int64(cx)) | (_spread(np.int64(cy)) << 1) | (_spread(np.int64(cz)) << 2)
    return out


@njit(cache=True)
def permute_rows(buf, order, scratch):
    """``buf[:n] = buf[order]`` (n = len(order)) through ``scratch`` (at least n rows, buf's columns)."""
    n = len(order)
    for r in range(n):
        scratch[r] = buf[order[r]]
    for r in range(n):
        buf[r] = scratch[r]


@njit(cache=True)
def renumber_table(keys, rows, new_row):
    """The voxel table's rows after the map's rows were permuted: ``rows[s] ← new_row[rows[s]]``."""
    for s in range(len(keys)):
        if keys[s] >= 0:
            rows[s] = new_row[rows[s]]
