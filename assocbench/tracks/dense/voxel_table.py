"""The point map's voxel index: which map point holds a voxel of space (one surfel per voxel). A
surface seen again from a new pose has pixels no map point lands on, so the projective merge alone
grows the map without bound. A sample ``q`` with world normal ``m`` lands in the cell

    key(q, m) = (⌊q_x/s_x⌋, ⌊q_y/s_y⌋, ⌊q_z/s_z⌋, c(m)),   c(m) = 2 a + [m_a < 0],  a = argmax_a |m_a|

(``s_a``: fusion's ``d_thr`` along the normal's dominant axis, so depth noise does not split a plane
into two layers, the voxel size along the others; the class keeps a thin wall's faces apart) and
merges into the point holding it or a neighbour along ``a`` (``held_cell``). A point's cell is fixed
when added. The table is open addressing with linear probing over int64 keys (20 bits per
coordinate, offset 2^19, the class in the low 3 bits; ``EMPTY``, ``GONE``), each key's row beside
it, rebuilt past half full.
"""

from __future__ import annotations

import numpy as np
from numba import njit

EMPTY = -1          # a slot never used
GONE = -2           # a removed key's slot (tombstone): probing goes on past it
OFFSET = 1 << 19    # cell coordinates are stored offset by this, in 20 bits each
_MIX = -7046029254386353131   # 0x9E3779B97F4A7C15 (Fibonacci hashing) as a signed int64


def new_table(size: int) -> tuple[np.ndarray, np.ndarray]:
    """An empty table of ``size`` slots (a power of two): ``(keys, rows)``, strided views of one
    (size, 2) array, so a key and its row share a cache line."""
    slots = np.empty((size, 2), np.int64)
    slots[:, 0], slots[:, 1] = EMPTY, 0
    return slots[:, 0], slots[:, 1]


@njit(cache=True, inline="always")
def cell_key(q0, q1, q2, m0, m1, m2, inv_size, inv_thick):
    """The packed key of the cell of ``q`` with normal ``m``, or −1 beyond the ±2^19 cells a
    coordinate holds."""
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
    """The map row holding ``key``, else the one holding its nearer then farther neighbour along the
    class's axis if that point lies within ``reach`` of ``q`` along it (half the thickness: parallel
    faces a few cm apart stay apart), else −1."""
    i = table_find(keys, rows, key)
    return i if i >= 0 else held_neighbour(keys, rows, key, q0, q1, q2, inv_thick, pos, reach)


@njit(cache=True, inline="always")
def held_neighbour(keys, rows, key, q0, q1, q2, inv_thick, pos, reach):
    """``held_cell``'s neighbour search: the row of the nearer, then farther, neighbour within
    ``reach``, or −1."""
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
    """Record that row ``row`` holds ``key``; returns 1 when a never-used slot was taken, 0 for a
    tombstone."""
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
    """Fill the cleared table with the keys of rows ``0..n−1`` (a key held twice keeps its first
    row); returns the slots in use."""
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
