"""The point map's rows in spatial order, so that its blocks are small boxes.

The map's index (``fusion``) skips blocks outside the view frustum, which pays only if a block's
points lie close together; rows appended as fusion adds them (and holes filled on removal) scatter
over the room. So ``fuse`` sorts the map once the rows added or moved since the last sort pass
``SORT_SHARE`` of it: stably, by the Morton (z-order) code of their ``CELL`` cell, which keeps
nearby cells near. ``benchmarks/dense_map_order.py`` measures it. Nothing computed from the map
depends on row order (ties break by ``born``), so sorting changes no number
(tests/tracks/dense/test_map_order.py).
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
