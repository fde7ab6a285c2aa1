"""The point map's voxel index: which map point holds a voxel of space (one surfel per voxel).

Fusion adds every pixel that no map point merged with. With the homework's projective merge alone
the map only grows: a surface seen again from a new pose has pixels on which no map point lands
(the points sit on the old pose's pixel grid), and each such pixel adds a point, so the density in
view climbs frame after frame (93k -> 249k points visited by the splat over 200 crates frames).
Bounding it takes a rule that does not depend on the pose: a new sample ``q`` with world normal
``m`` lands in the cell

    key(q, m) = (⌊q_x/s_x⌋, ⌊q_y/s_y⌋, ⌊q_z/s_z⌋, c(m)),   c(m) = 2 a + [m_a < 0],  a = argmax_a |m_a|

(6 classes; ``s_a`` = the cell's thickness ``h`` along the normal's dominant axis ``a``, the voxel
size ``s`` along the other two; the class keeps the two faces of a thin wall, or the floor and the
wall in a corner cell, apart), and when a map point already holds that cell, or else one of its two
neighbours along ``a`` (``held_cell``; the nearer first), the sample merges into it instead of being
added. Thickness and neighbours matter: the depth noise moves samples of one surface along its
normal (σ 5-15 mm at 1.5-2.7 m), and a plane lying on a cell face splits into a layer of points in
front and one behind, each the mean of one side of the noise (0.8 σ off: 4.6 mm median on the
synthetic room's back wall with 2 cm cubes); so the thickness is fusion's distance gate ``d_thr``
(5 cm) and a sample whose own cell is free joins a neighbour's point lying within half the
thickness of it along the axis (a reach of the noise's scale: parallel faces a few cm apart, a
crate's slats, stay apart; merged, they slid frame-to-model tracking on a 500-frame crates path
60 mm along them, 33 wrong steps, against 8 with the reach). The cell of a point is fixed when it is added (``PointMap._key``): the
point's merged position drifts by less than the noise, and re-keying it would move it between
cells. The map then holds at most one point per occupied cell: its size plateaus once the scene is
seen (ElasticFusion and voxel-hashed surfel maps bound their density the same way).

The table is open addressing with linear probing over int64 keys (cell coordinates packed 20 bits
each, offset by 2^19, and the class in the low 3 bits: ±5 km at 1 cm), ``EMPTY`` and ``GONE``
(a removed point's tombstone) marking free slots; ``rows`` holds the map row of each key, beside
it in memory (``new_table``: two views of one array, a slot's key and row in one cache line). Fusion's
removal moves rows, so it tells the table (``table_move``); a removed point is deleted at once
(``table_delete``) so that a sample in its cell adds a fresh point. The table is rebuilt from the
map's keys when its slots in use (tombstones included) would pass half its size.
"""

from __future__ import annotations

import numpy as np
from numba import njit

EMPTY = -1          # a slot never used
GONE = -2           # a removed key's slot (tombstone): probing goes on past it
OFFSET = 1 << 19    # cell coordinates are stored offset by this, in 20 bits each
_MIX = -7046029254386353131   # 0x9E3779B97F4A7C15 (Fibonacci hashing) as a signed int64


def new_table(size: int) -> tuple[np.ndarray, np.ndarray]:
    """An empty table of ``size`` slots (a power of two): ``(keys, rows)``, two strided views of one
    (size, 2) array, so that a slot's key and row share a cache line: a probe that finds its key
    reads its row without a second miss (fusion's cell pass probes a table of megabytes at random)."""
    slots = np.empty((size, 2), np.int64)
    slots[:, 0], slots[:, 1] = EMPTY, 0
    return slots[:, 0], slots[:, 1]


@njit(cache=True, inline="always")
def cell_key(q0, q1, q2, m0, m1, m2, inv_size, inv_thick):
    """The packed key of the cell holding the point ``q`` with normal ``m`` (module docstring), or
    −1 when ``q`` lies beyond the ±2^19 cells a coordinate can hold."""
    a0, a1, a2 = abs(m0), abs(m1), abs(m2)
    if a0 >= a1 and a0 >= a2:
        c = 0 if m0 >= 0 else 1
    elif a1 >= a2:
        c = 2 if m1 >= 0 else 3
    else:
        c = 4 if m2 >= 0 else 5
    axis = c >> 1
    i0 = np.floor(q0 * (inv_thick if axis == 0 else inv_size))
    i1 = np.floor(q1 * (inv_thick if axis == 1 else inv_size))
    i2 = np.floor(q2 * (inv_thick if axis == 2 else inv_size))
    if not (abs(i0) < OFFSET and abs(i1) < OFFSET and abs(i2) < OFFSET):
        return -1
    return (((int(i0) + OFFSET) << 43) | ((int(i1) + OFFSET) << 23) | ((int(i2) + OFFSET) << 3)) | c


@njit(cache=True, inline="always")
def _slot(key, mask):
    h = key * _MIX
    return (h ^ (h >> 29)) & mask


@njit(cache=True, inline="always")
def _slot_of(keys, key):
    """The slot holding ``key``, or −1."""
    mask = len(keys) - 1
    s = _slot(key, mask)
    while keys[s] != EMPTY:
        if keys[s] == key:
            return s
        s = (s + 1) & mask
    return -1


@njit(cache=True, inline="always")
def table_find(keys, rows, key):
    """The map row holding ``key``, or −1."""
    s = _slot_of(keys, key)
    return rows[s] if s >= 0 else -1


@njit(cache=True, inline="always")
def held_cell(keys, rows, key, q0, q1, q2, inv_thick, pos, reach):
    """The map row holding ``key`` (the cell of the sample ``q``), else the one holding the nearer
    then the farther of its neighbours along the class's axis (the normal's dominant axis) if that
    point lies within ``reach`` of ``q`` along the axis, else −1. The reach keeps parallel faces a
    few cm apart (a crate's slats) from merging across cells: it is half the thickness, the
    noise's scale, not the cell's."""
    i = table_find(keys, rows, key)
    return i if i >= 0 else held_neighbour(keys, rows, key, q0, q1, q2, inv_thick, pos, reach)


@njit(cache=True, inline="always")
def held_neighbour(keys, rows, key, q0, q1, q2, inv_thick, pos, reach):
    """``held_cell``'s second half: the row holding the nearer, then the farther, neighbour of the
    cell ``key`` along the class's axis whose point lies within ``reach`` of ``q`` along it, or −1."""
    axis = (key & 7) >> 1
    coord = q0 if axis == 0 else (q1 if axis == 1 else q2)
    step = np.int64(1) << (43 - 20 * axis)          # one cell along that axis in the packed key
    frac = coord * inv_thick - np.floor(coord * inv_thick)
    first = step if frac >= 0.5 else -step
    for side in (first, -first):
        i = table_find(keys, rows, key + side)
        if i >= 0 and abs(pos[i, axis] - coord) < reach:
            return i
    return -1


@njit(cache=True)
def table_insert(keys, rows, key, row):
    """Record that map row ``row`` holds ``key`` (absent: the caller found it so); returns 1 when a
    never-used slot was taken (the count of slots in use grows), else 0 (a tombstone reused)."""
    mask = len(keys) - 1
    s = _slot(key, mask)
    while keys[s] >= 0:
        s = (s + 1) & mask
    fresh = 1 if keys[s] == EMPTY else 0
    keys[s], rows[s] = key, row
    return fresh


@njit(cache=True)
def table_delete(keys, rows, key, row):
    """Forget ``key`` if row ``row`` holds it (a row whose key another row holds is not in the table)."""
    s = _slot_of(keys, key) if key >= 0 else -1
    if s >= 0 and rows[s] == row:
        keys[s] = GONE


@njit(cache=True)
def table_move(keys, rows, key, src, dst):
    """The point of ``key`` moved from map row ``src`` to ``dst``."""
    s = _slot_of(keys, key) if key >= 0 else -1
    if s >= 0 and rows[s] == src:
        rows[s] = dst


@njit(cache=True)
def table_build(keys, rows, point_keys, n):
    """Fill the (cleared) table with the keys of rows ``0..n−1`` (a key held twice, as in a map built
    from arrays, keeps its first row); returns the slots in use."""
    keys.fill(EMPTY)
    used = 0
    for i in range(n):
        k = point_keys[i]
        if k >= 0 and table_find(keys, rows, k) < 0:
            used += table_insert(keys, rows, k, i)
    return used


@njit(cache=True)
def keys_of(pos, nrm, n, inv_size, inv_thick, out):
    """``out[i] = cell_key(pos[i], nrm[i])`` for rows ``0..n−1`` (−1 for a NaN position)."""
    for i in range(n):
        if pos[i, 0] == pos[i, 0] and pos[i, 1] == pos[i, 1] and pos[i, 2] == pos[i, 2]:
            out[i] = cell_key(pos[i, 0], pos[i, 1], pos[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2], inv_size, inv_thick)
        else:
            out[i] = -1
