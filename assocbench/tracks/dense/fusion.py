"""Point-based fusion of depth frames into a point map (the dense-SLAM homework, section 3 and
bonus).

Every map point ``p`` with normal ``n_p`` and weight ``w`` is projected into the frame at
``(R, t)``, ``p_c = Rᵀ (p − t)``, ``(u, v) = round(f x/z + c)``, and kept by pass 1 (``z > 0``, in
the image, the pixel valid) and pass 2 (``q = R V[v,u] + t``, ``n_q = R N[v,u]``,
``|p − q| < d_thr``, ``n_p · n_q > cos angle_deg``). A kept point is **merged**::

    p   ← (w p + R q + t) / (w + 1)
    n_p ← (w n_p + R n_q) / (w + 1),   n_p ← n_p / ‖n_p‖
    w   ← w + 1,   last_seen ← k

A valid pixel no point merged with is **added**; with cells (``voxel``, ``voxel_table``) it first
merges into the point holding its cell, so the map keeps one point per cell and levels off once the
scene is seen. A frame's samples of a point are summed and merged once, as one measurement
(``_apply_samples``). Then (the bonus) unstable points (``w < stable_weight``) are **removed** when
dormant (not merged for ``dormant_frames``) or seen through (``z < depth[v,u] − d_thr``). Truth
rides along with the same weights; a point whose pixels lie on two geoms becomes ``MIXED_GEOM``.

The passes are compiled; removal fills holes from the end (row order is not kept). **Index**: rows
form blocks of ``BLOCK`` with a bounding box and the oldest unstable ``last_seen``; the map is kept
in spatial order (``map_order``), and the merge pass visits only blocks in the frustum or holding a
point about to turn dormant. Skipped blocks provably change nothing: ``index=False`` gives the same
map bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...errors import UserError
from ...models.depth_frame import NO_GEOM, DepthFrame
from ...validation import check_number
from .map_order import CELL, SORT_SHARE, morton_keys, permute_rows, renumber_table
from .settings import FusionConfig
from .voxel_table import (
    cell_key,
    held_neighbour,
    keys_of,
    new_table,
    table_build,
    table_delete,
    table_find,
    table_insert,
    table_move,
)

MIXED_GEOM = -2   # truth of a map point that fused pixels of different geoms
BLOCK = 64        # points per block of the map's index: a fifth of a 320-pixel row, so a block's box is small
NEVER = np.iinfo(np.int64).max   # ``oldest`` of a block without unstable points
# a point's sums of one ``fuse`` call, one row of ``_fsum``: Σq, Σm, Σtruth (0-8), their count
# (COUNT) and the call they belong to (CALL, exact in a float below 2^53). One row, not three
# arrays: the cell pass adds samples to points at random rows, and each array is a cache miss
# more (benchmarks/dense_fusion_ab.py)
SUM_COLUMNS, COUNT, CALL = 11, 9, 10


@dataclass(frozen=True)
class FusionStats:
    """What one ``fuse`` call did: ``merged``, ``added``, removed (``dormant``, ``outliers``),
    ``considered`` (passed pass 1), ``mixed``, the map size after, ``scanned`` (points visited),
    ``binned`` (pixels merged into their cell's point) and ``dropped`` (their normals disagreed)."""

    merged: int
    added: int
    removed: int
    dormant: int = 0
    outliers: int = 0
    considered: int = 0
    mixed: int = 0
    size: int = 0
    scanned: int = 0
    binned: int = 0
    dropped: int = 0


class PointMap:
    """Surfel-like points in world coordinates: ``positions``, unit ``normals``, ``weights`` (1 +
    merges), ``last_seen``, and for scoring only ``true_points``, ``geom`` (``NO_GEOM``,
    ``MIXED_GEOM``) and ``born`` (the point's serial: rows move on removal and ``sort_spatially``,
    called past ``sort_share``). Views of buffers with spare capacity that ``fuse`` updates in
    place: read, do not write."""

    # name, columns, dtype; _remove is per-frame work space of the kernels, kept with the
    # map (like ``_used``) because a fresh array costs a page fault per 4 KiB on first write, which
    # for a 200k-point map is as much as the fusion itself
    _BUFFERS = (("_pos", 3, np.float64), ("_nrm", 3, np.float64), ("_tp", 3, np.float64), ("_w", 0, np.float64),
                ("_last", 0, np.int64), ("_geom", 0, np.int64), ("_remove", 0, np.int64), ("_key", 0, np.int64),
                ("_fsum", SUM_COLUMNS, np.float64), ("_touched", 0, np.int64),
                ("_born", 0, np.int64))
    # the fields a point carries (``sort_spatially`` moves them with it; the rest is per-call work space)
    _FIELDS = ("_pos", "_nrm", "_tp", "_w", "_last", "_geom", "_key", "_born")

    def __init__(self, capacity: int = 0) -> None:
        self._n = 0
        self._used = np.zeros(0, dtype=np.bool_)
        self._stable = -np.inf   # the stable weight the blocks' ``oldest`` assumes (-inf: every point counted)
        self._calls = 0           # ``fuse`` calls so far: ``_fsum[:, CALL]`` says in which one a point's frame sums began
        self._voxel = (0.0, 0.0)  # the cells (size, thickness) ``_key`` and the voxel table hold (0: none)
        (self._table_keys, self._table_rows), self._table_used = new_table(16), 0
        self._serial = 0          # the ``born`` serial of the next point added
        self._unsorted = 0        # rows added or moved since the last ``sort_spatially``
        self.sort_share: float | None = SORT_SHARE   # ``fuse`` sorts past this share of unsorted rows (None: never)
        self._alloc(max(int(capacity), 16))

    def _alloc(self, cap: int) -> None:
        """Buffers of ``cap`` rows holding the current points, written once so their pages are
        mapped now."""
        n = self._n
        for name, cols, dtype in self._BUFFERS:
            buf = np.empty((cap, cols) if cols else cap, dtype=dtype)
            buf.fill(0)
            old = getattr(self, name, None)
            if old is not None:
                buf[:n] = old[:n]
            setattr(self, name, buf)
        blocks = -(-cap // BLOCK)
        lo, hi, oldest = np.full((blocks, 3), np.inf), np.full((blocks, 3), -np.inf), np.full(blocks, NEVER)
        used = -(-n // BLOCK)
        if hasattr(self, "_lo"):
            lo[:used], hi[:used], oldest[:used] = self._lo[:used], self._hi[:used], self._oldest[:used]
        self._lo, self._hi, self._oldest = lo, hi, oldest

    def _reindex(self) -> None:
        """Every block's box and ``oldest`` from its points (all points counted: true for any stable weight)."""
        _index_blocks(self._pos, self._w, self._last, self._n, self._lo, self._hi, self._oldest,
                      np.arange(-(-self._n // BLOCK)), np.inf)
        self._stable = -np.inf

    def index_cells(self, voxel: float, thick: float, extra: int) -> None:
        """Make the voxel table hold the current points' cells (``voxel``, ``thick``) with room for
        ``extra`` keys."""
        if (voxel, thick) != self._voxel:
            keys_of(self._pos, self._nrm, self._n, 1.0 / voxel, 1.0 / thick, self._key)
            self._voxel, self._table_used = (voxel, thick), len(self._table_keys)   # forces the rebuild below
        if 2 * (self._table_used + extra) > len(self._table_keys):
            # the power of two above 2 (n + extra): at most half full once the frame's keys are in; a
            # bigger, emptier table makes the add pass's probes miss the caches more
            size = 1 << max(4, int(2 * (self._n + extra)).bit_length())
            self._table_keys, self._table_rows = new_table(size)
            self._table_used = table_build(self._table_keys, self._table_rows, self._key, self._n)

    def blocks_in_view(self, K, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Ascending ids of the blocks whose box meets the view frustum of ``K`` at ``(R, t)``."""
        return frustum_blocks(self._lo, self._hi, -(-self._n // BLOCK), np.ascontiguousarray(R, dtype=np.float64),
                              np.ascontiguousarray(t, dtype=np.float64).reshape(3), float(K.f), float(K.cx),
                              float(K.cy), K.width, K.height)

    def reserve(self, extra: int) -> None:
        """Make room for ``extra`` more points (capacity at least doubles when it grows)."""
        need = self._n + int(extra)
        if need > len(self._w):
            self._alloc(max(need, 2 * len(self._w)))

    def _used_mask(self, pixels: int) -> np.ndarray:
        """The all-false (pixels,) work mask of pixels merged with, reused across frames."""
        if len(self._used) != pixels:
            self._used = np.zeros(pixels, dtype=np.bool_)
        self._used.fill(False)
        return self._used

    @classmethod
    def from_arrays(cls, positions: np.ndarray, normals: np.ndarray, weights=1.0, last_seen=0,
                    true_points: np.ndarray | None = None, geom=None) -> PointMap:
        """A map holding given points; scalars broadcast; no truth: NaN true points, ``NO_GEOM``."""
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        n = len(pos)
        m = cls(n)
        m._n = n
        m._pos[:n] = pos
        m._nrm[:n] = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        m._w[:n] = np.broadcast_to(np.asarray(weights, dtype=np.float64), (n,))
        m._last[:n] = np.broadcast_to(np.asarray(last_seen, dtype=np.int64), (n,))
        m._tp[:n] = np.nan if true_points is None else np.asarray(true_points, dtype=np.float64).reshape(-1, 3)
        m._geom[:n] = np.broadcast_to(np.asarray(NO_GEOM if geom is None else geom, dtype=np.int64), (n,))
        m._born[:n] = np.arange(n)
        m._serial = m._unsorted = n
        m._reindex()
        return m

    def copy(self) -> PointMap:
        m = PointMap.from_arrays(self.positions, self.normals, self.weights, self.last_seen, self.true_points, self.geom)
        m._born[:len(m)], m._serial = self.born, self._serial
        return m

    def sort_spatially(self) -> None:
        """Sort the rows by the Morton code of their cell (``map_order``), stably; changes no
        result."""
        n = self._n
        order = np.argsort(morton_keys(self._pos, n, 1.0 / CELL), kind="stable")
        for name in self._FIELDS:
            buf = getattr(self, name)
            permute_rows(buf, order, np.empty_like(buf[:n]))
        new_row = np.empty(n, np.int64)
        new_row[order] = np.arange(n)
        renumber_table(self._table_keys, self._table_rows, new_row)
        if np.isfinite(self._stable):   # the boxes, and ``oldest`` for the stable weight fusion last used
            _index_blocks(self._pos, self._w, self._last, n, self._lo, self._hi, self._oldest,
                          np.arange(-(-n // BLOCK)), self._stable)
        else:
            self._reindex()
        self._unsorted = 0

    def __len__(self) -> int:
        return self._n

    positions = property(lambda self: self._pos[:self._n], doc="(n, 3) world positions")
    normals = property(lambda self: self._nrm[:self._n], doc="(n, 3) unit normals")
    weights = property(lambda self: self._w[:self._n], doc="(n,) 1 + number of merges")
    last_seen = property(lambda self: self._last[:self._n], doc="(n,) frame of the last merge/addition")
    true_points = property(lambda self: self._tp[:self._n], doc="(n, 3) truth: fused true points")
    geom = property(lambda self: self._geom[:self._n], doc="(n,) truth: geom id, NO_GEOM, MIXED_GEOM")
    born = property(lambda self: self._born[:self._n], doc="(n,) serial of the point's addition (older: lower)")


@njit(cache=True)
def _index_blocks(pos, w, last, n, lo, hi, oldest, blocks, stable_w):
    """Recompute each block's box and ``oldest`` (least ``last`` with ``w < stable_w``); NaN widens
    nothing."""
    for b in blocks:
        for a in range(3):
            lo[b, a], hi[b, a] = np.inf, -np.inf
        first = NEVER
        for i in range(b * BLOCK, min(n, (b + 1) * BLOCK)):
            for a in range(3):
                lo[b, a] = min(lo[b, a], pos[i, a]) if pos[i, a] == pos[i, a] else lo[b, a]
                hi[b, a] = max(hi[b, a], pos[i, a]) if pos[i, a] == pos[i, a] else hi[b, a]
            if w[i] < stable_w and last[i] < first:
                first = last[i]
        oldest[b] = first


@njit(cache=True, inline="always")   # inlined: a call passing seven arrays counts their references
def _widen(lo, hi, oldest, i, pos, w, last, stable_w):
    """Block of row ``i`` widened to hold the point now in row ``i`` (added or moved in)."""
    b = i // BLOCK
    for a in range(3):
        if pos[i, a] == pos[i, a]:
            lo[b, a] = min(lo[b, a], pos[i, a])
            hi[b, a] = max(hi[b, a], pos[i, a])
    if w[i] < stable_w and last[i] < oldest[b]:
        oldest[b] = last[i]


@njit(cache=True)
def _outside(lo, hi, b, R, t, a0, a1, a2):
    """Whether block ``b``'s box lies wholly behind the plane ``a · p_c = 0`` through the camera
    centre, by more than a relative 1e-9 (a point on it is never culled)."""
    top = 0.0
    scale = 0.0
    for r in range(3):
        m = R[r, 0] * a0 + R[r, 1] * a1 + R[r, 2] * a2
        c, h = 0.5 * (lo[b, r] + hi[b, r]) - t[r], 0.5 * (hi[b, r] - lo[b, r])
        top += m * c + abs(m) * h
        scale += abs(m) * (abs(c) + h)
    return top < -1e-9 * scale


@njit(cache=True)
def frustum_blocks(lo, hi, blocks, R, t, f, cx, cy, width, height):
    """Ascending ids of the blocks not wholly outside one of the five planes of a pixel's ray
    (``z > 0``, ``f x + (cx + ½) z ≥ 0``, ``(W − cx − ½) z − f x > 0``, the same for ``v``); an
    empty block is outside."""
    out = np.empty(blocks, np.int64)
    k = 0
    for b in range(blocks):
        if not lo[b, 0] <= hi[b, 0]:
            continue
        if (_outside(lo, hi, b, R, t, 0.0, 0.0, 1.0) or _outside(lo, hi, b, R, t, f, 0.0, cx + 0.5)
                or _outside(lo, hi, b, R, t, -f, 0.0, width - cx - 0.5)
                or _outside(lo, hi, b, R, t, 0.0, f, cy + 0.5)
                or _outside(lo, hi, b, R, t, 0.0, -f, height - cy - 0.5)):
            continue
        out[k] = b
        k += 1
    return out[:k]


@njit(cache=True)
def _merge_blocks(in_view, oldest, blocks, k, dormant_frames, drop_dormant):
    """The blocks the merge pass visits: in view, and those that may hold a dormant point."""
    out = np.empty(blocks, np.int64)
    m = 0
    j = 0
    for b in range(blocks):
        seen = j < len(in_view) and in_view[j] == b
        if seen:
            j += 1
        if seen or (drop_dormant and oldest[b] != NEVER and k - oldest[b] >= dormant_frames):
            out[m] = b
            m += 1
    return out[:m]


@njit(cache=True, inline="always")   # inlined: a call passing arrays would count their references a point
def pixel_of(pos, i, R, t, f, cx, cy, width, height):
    """(flat pixel, z) of point ``i`` seen from ``(R, t)``, the nearest pixel of
    ``(f x/z + cx, f y/z + cy)``; −1 behind the camera or outside (NaN included). The splat's and
    fusion's one projection."""
    dx, dy, dz = pos[i, 0] - t[0], pos[i, 1] - t[1], pos[i, 2] - t[2]
    z = R[0, 2] * dx + R[1, 2] * dy + R[2, 2] * dz
    if not z > 0.0:
        return -1, z
    x = R[0, 0] * dx + R[1, 0] * dy + R[2, 0] * dz
    y = R[0, 1] * dx + R[1, 1] * dy + R[2, 1] * dz
    uf = np.floor(f * x / z + cx + 0.5)
    vf = np.floor(f * y / z + cy + 0.5)
    if not (uf >= 0.0 and uf < width and vf >= 0.0 and vf < height):
        return -1, z
    return int(vf) * width + int(uf), z


@njit(cache=True, inline="always")
def _take_sample(geom, fsum, call, touched, nt, i, q0, q1, q2, m0, m1, m2, TP, G, j):
    """Add sample ``q``, ``m`` (truth ``TP[j]``, ``G[j]``) to point ``i``'s sums (``fsum``: Σq, Σm,
    Σtruth, ``COUNT``); returns (touched points, 1 when its truth turned mixed)."""
    x = (q0, q1, q2, m0, m1, m2, TP[j, 0], TP[j, 1], TP[j, 2])
    if fsum[i, CALL] != call:
        for r in range(9):
            fsum[i, r] = x[r]
        fsum[i, COUNT], fsum[i, CALL], touched[nt] = 1.0, call, i
        nt += 1
    else:
        for r in range(9):
            fsum[i, r] += x[r]
        fsum[i, COUNT] += 1.0
    if geom[i] != G[j] and geom[i] >= 0:   # NO_GEOM stays; a first disagreement: MIXED_GEOM
        geom[i] = -2
        return nt, 1
    return nt, 0


@njit(cache=True)
def _apply_samples(pos, nrm, w, last, tp, fsum, touched, nt, k, lo, hi, oldest, stable_w):
    """Merge each touched point's mean sample ``(q̄, m̄, t̄) = Σ / c`` as ONE measurement of weight
    1:

        p ← (w p + q̄) / (w + 1),   n ← (w n + m̄) / (w + 1),  n ← n / ‖n‖,
        true ← (w true + t̄) / (w + 1),   w ← w + 1,   last_seen ← k

    (one frame's pixels share its pose: counted singly, one frame would outvote many). A new point
    (``w = 0``) becomes its mean."""
    for r in range(nt):     # reciprocals: 3 divisions a point, not 15
        i = touched[r]
        wi = w[i]
        mean, keep = 1.0 / (fsum[i, COUNT] * (wi + 1)), wi / (wi + 1)     # Σ/c/(w+1) and w/(w+1)
        for a in range(3):
            pos[i, a] = keep * pos[i, a] + mean * fsum[i, a]
            tp[i, a] = keep * tp[i, a] + mean * fsum[i, a + 6]
        a0 = keep * nrm[i, 0] + mean * fsum[i, 3]
        a1 = keep * nrm[i, 1] + mean * fsum[i, 4]
        a2 = keep * nrm[i, 2] + mean * fsum[i, 5]
        inv = 1.0 / np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        nrm[i, 0], nrm[i, 1], nrm[i, 2] = a0 * inv, a1 * inv, a2 * inv
        w[i] = wi + 1
        last[i] = k
        _widen(lo, hi, oldest, i, pos, w, last, stable_w)


@njit(cache=True)
def _merge_pass(pos, nrm, w, last, tp, geom, key, fsum, call, touched, n, R, t, f, cx, cy, W, H, V, N, TP, G, d_thr, cos_thr, stable_w,
                dormant_frames, k, drop_dormant, drop_outliers, used, remove, blocks, lo, hi, oldest, table_keys,
                table_rows):
    """The merge pass over ``blocks``: project, filter, sample, mark removals (freeing their cells),
    and recompute the visited blocks' boxes. Returns (merged, considered, dormant, outliers, mixed,
    removals, scanned, touched)."""
    merged = considered = dormant = outliers = mixed = nrem = scanned = nt = 0
    for b in blocks:   # the loops are nested, not a call per block: a call that passes a dozen arrays
        first, end = b * BLOCK, min(n, (b + 1) * BLOCK)   # costs their reference counting
        scanned += end - first
        box, oldest_b = (np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf), NEVER   # the block's, anew
        for i in range(first, end):
            box = _grown(box, pos, i)
            unstable = w[i] < stable_w
            if unstable and last[i] < oldest_b:
                oldest_b = last[i]
            j, z = pixel_of(pos, i, R, t, f, cx, cy, W, H)
            if j >= 0:                                        # pass 1: in front, in the image
                d = V[j, 2]                                  # the vertex's z is the depth
                if d > 0 and np.isfinite(N[j, 0]):
                    considered += 1
                    q0 = R[0, 0] * V[j, 0] + R[0, 1] * V[j, 1] + R[0, 2] * V[j, 2] + t[0]   # R q + t
                    q1 = R[1, 0] * V[j, 0] + R[1, 1] * V[j, 1] + R[1, 2] * V[j, 2] + t[1]
                    q2 = R[2, 0] * V[j, 0] + R[2, 1] * V[j, 1] + R[2, 2] * V[j, 2] + t[2]
                    m0 = R[0, 0] * N[j, 0] + R[0, 1] * N[j, 1] + R[0, 2] * N[j, 2]          # R n_q
                    m1 = R[1, 0] * N[j, 0] + R[1, 1] * N[j, 1] + R[1, 2] * N[j, 2]
                    m2 = R[2, 0] * N[j, 0] + R[2, 1] * N[j, 1] + R[2, 2] * N[j, 2]
                    e0, e1, e2 = pos[i, 0] - q0, pos[i, 1] - q1, pos[i, 2] - q2
                    if (e0 * e0 + e1 * e1 + e2 * e2 < d_thr * d_thr
                            and nrm[i, 0] * m0 + nrm[i, 1] * m1 + nrm[i, 2] * m2 > cos_thr):   # pass 2
                        nt, mx = _take_sample(geom, fsum, call, touched, nt, i, q0, q1, q2, m0, m1, m2, TP, G, j)
                        mixed += mx
                        used[j] = True
                        merged += 1
                        continue
                if drop_outliers and unstable and d > 0 and z < d - d_thr:   # seen through
                    remove[nrem] = i
                    nrem += 1
                    table_delete(table_keys, table_rows, key[i], i)
                    outliers += 1
                    continue
            if drop_dormant and unstable and k - last[i] >= dormant_frames:
                remove[nrem] = i
                nrem += 1
                dormant += 1
                table_delete(table_keys, table_rows, key[i], i)
        lo[b, 0], lo[b, 1], lo[b, 2], hi[b, 0], hi[b, 1], hi[b, 2] = box
        oldest[b] = oldest_b
    return merged, considered, dormant, outliers, mixed, nrem, scanned, nt


@njit(cache=True, inline="always")
def _grown(box, pos, i):
    """``box`` (lo xyz, hi xyz) widened to hold point ``i`` (NaN widens nothing)."""
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    return (min(box[0], x) if x == x else box[0], min(box[1], y) if y == y else box[1],
            min(box[2], z) if z == z else box[2], max(box[3], x) if x == x else box[3],
            max(box[4], y) if y == y else box[4], max(box[5], z) if z == z else box[5])


@njit(cache=True)
def _add_pass(pos, nrm, w, last, tp, geom, key, born, serial, fsum, call, touched, nt, n, R, t, V, N, TP, G,
              used, k, lo, hi, oldest, stable_w, inv_voxel, inv_thick, cos_thr, table_keys, table_rows, width):
    """Unmerged valid pixels (raster order): with cells, a sample of the point holding their cell if
    the normals agree, else dropped; otherwise appended with weight 0. Returns (size, merged,
    dropped, new slots, mixed, touched)."""
    binned = dropped = fresh = mixed = 0
    last_cell = last_row = -1   # the table's entries only gain keys in this pass, so a found key stays found
    up_cell, up_row = np.full(width, -1, np.int64), np.full(width, -1, np.int64)
    u = -1
    for j in range(V.shape[0]):
        u = 0 if u + 1 == width else u + 1      # the pixel's column
        if used[j] or not (V[j, 2] > 0) or not np.isfinite(N[j, 0]):
            continue
        q0 = R[0, 0] * V[j, 0] + R[0, 1] * V[j, 1] + R[0, 2] * V[j, 2] + t[0]
        q1 = R[1, 0] * V[j, 0] + R[1, 1] * V[j, 1] + R[1, 2] * V[j, 2] + t[1]
        q2 = R[2, 0] * V[j, 0] + R[2, 1] * V[j, 1] + R[2, 2] * V[j, 2] + t[2]
        m0 = R[0, 0] * N[j, 0] + R[0, 1] * N[j, 1] + R[0, 2] * N[j, 2]
        m1 = R[1, 0] * N[j, 0] + R[1, 1] * N[j, 1] + R[1, 2] * N[j, 2]
        m2 = R[2, 0] * N[j, 0] + R[2, 1] * N[j, 1] + R[2, 2] * N[j, 2]
        cell = cell_key(q0, q1, q2, m0, m1, m2, inv_voxel, inv_thick) if inv_voxel > 0 else -1
        if cell >= 0:
            if cell == last_cell:     # the previous pixel's cell, held by ``last_row``: no probe
                i = last_row
            elif cell == up_cell[u]:
                last_cell, last_row = cell, up_row[u]
                i = last_row
            else:
                i = table_find(table_keys, table_rows, cell)
                if i >= 0:
                    last_cell, last_row = cell, i
                    up_cell[u], up_row[u] = cell, i
                else:
                    i = held_neighbour(table_keys, table_rows, cell, q0, q1, q2, inv_thick, pos, 0.5 / inv_thick)
            if i >= 0:
                if nrm[i, 0] * m0 + nrm[i, 1] * m1 + nrm[i, 2] * m2 > cos_thr:
                    nt, mx = _take_sample(geom, fsum, call, touched, nt, i, q0, q1, q2, m0, m1, m2, TP, G, j)
                    mixed += mx
                    binned += 1
                else:
                    dropped += 1
                continue
            fresh += table_insert(table_keys, table_rows, cell, n)
            last_cell, last_row = cell, n
            up_cell[u], up_row[u] = cell, n
        pos[n, 0], pos[n, 1], pos[n, 2] = q0, q1, q2   # for the cell lookups until _apply_samples
        nrm[n, 0], nrm[n, 1], nrm[n, 2] = m0, m1, m2
        for a in range(3):
            tp[n, a] = 0.0
        w[n] = 0.0                                      # no frame merged yet: _apply_samples makes it 1
        last[n] = k
        geom[n] = G[j]
        key[n] = cell
        born[n] = serial
        serial += 1
        fsum[n, CALL] = -1.0                            # not this call's: the sample below starts its sums
        nt, _ = _take_sample(geom, fsum, call, touched, nt, n, q0, q1, q2, m0, m1, m2, TP, G, j)
        if n % BLOCK == 0:
            b = n // BLOCK
            for a in range(3):
                lo[b, a], hi[b, a] = np.inf, -np.inf
            oldest[b] = NEVER
        _widen(lo, hi, oldest, n, pos, w, last, stable_w)
        n += 1
    return n, binned, dropped, fresh, mixed, nt


@njit(cache=True)
def _remove_pass(pos, nrm, w, last, tp, geom, key, born, n, remove, nrem, lo, hi, oldest, stable_w, table_keys,
                 table_rows):
    """Remove ``remove[:nrem]`` (ascending), filling the holes below ``n − nrem`` with the survivors
    above, telling blocks and cells."""
    m = n - nrem
    holes = 0
    while holes < nrem and remove[holes] < m:
        holes += 1
    above = holes               # remove[above:] are the removed indices >= m, to be skipped
    src = m
    for r in range(holes):
        while above < nrem and remove[above] == src:
            src += 1
            above += 1
        hole = remove[r]
        for a in range(3):
            pos[hole, a], nrm[hole, a], tp[hole, a] = pos[src, a], nrm[src, a], tp[src, a]
        w[hole], last[hole], geom[hole], key[hole], born[hole] = w[src], last[src], geom[src], key[src], born[src]
        table_move(table_keys, table_rows, key[src], src, hole)
        _widen(lo, hi, oldest, hole, pos, w, last, stable_w)
        src += 1
    return m


def _check_pose(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = np.ascontiguousarray(R, dtype=np.float64)
    t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
    if R.shape != (3, 3) or t.shape != (3,) or not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        raise UserError(f"fuse: the pose must be a finite 3x3 rotation R and 3-vector t, got shapes {R.shape} "
                        f"and {t.shape}")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise UserError("fuse: R is not a rotation (RᵀR ≠ I or det < 0): pass the camera-to-world rotation")
    return R, t


def _frame_arrays(frame: DepthFrame) -> tuple[np.ndarray, ...]:
    """The frame's maps flattened to pixels ``j = v W + u`` in the kernels' dtypes."""
    h, w = frame.depth.shape
    if ((frame.K.width, frame.K.height) != (w, h) or frame.vertices.shape != (h, w, 3)
            or frame.normals.shape != (h, w, 3)):
        raise UserError(f"fuse: frame maps {frame.depth.shape}/{frame.vertices.shape}/{frame.normals.shape} "
                        f"disagree with its intrinsics {frame.K.width}x{frame.K.height}: build it with depth_frame()")
    flat = lambda a, c: np.ascontiguousarray(a, dtype=np.float64).reshape(-1, c)  # noqa: E731
    tp = flat(frame.true_points, 3) if frame.true_points is not None else np.full((h * w, 3), np.nan)
    geom = (np.ascontiguousarray(frame.geom, dtype=np.int64).reshape(-1) if frame.geom is not None
            else np.full(h * w, NO_GEOM, np.int64))
    return flat(frame.vertices, 3), flat(frame.normals, 3), tp, geom


def fuse(pmap: PointMap, frame: DepthFrame, R: np.ndarray, t: np.ndarray, k: int,
         cfg: FusionConfig | None = None, index: bool = True) -> FusionStats:
    """Fuse ``frame`` at the estimated pose ``(R, t)`` as frame ``k`` into ``pmap`` in place (merge,
    add, remove). ``index=False``: every point (same result)."""
    cfg = FusionConfig() if cfg is None else cfg
    if not isinstance(cfg, FusionConfig):   # a FusionConfig was checked when it was made (frozen)
        raise UserError(f"fuse: cfg must be a FusionConfig, got {type(cfg).__name__}")
    R, t = _check_pose(R, t)
    k = check_number(int(k) if isinstance(k, np.integer) else k, "fuse: frame index k", integer=True, lo=0)
    V, N, TP, G = _frame_arrays(frame)
    K = frame.K
    h, w = frame.depth.shape
    n = len(pmap)
    m = pmap
    m.reserve(h * w)            # before the kernels: the work space must hold n rows, the adds h·w more
    stable = float(cfg.stable_weight)
    if m._stable not in (-np.inf, stable):   # the blocks' ``oldest`` counted another stable weight's points
        m._reindex()
    used, remove = m._used_mask(h * w), m._remove
    m._calls += 1
    if cfg.voxel > 0:
        m.index_cells(float(cfg.voxel), max(float(cfg.voxel), float(cfg.d_thr)), h * w)
        table_keys, table_rows = m._table_keys, m._table_rows
    else:   # no cells: nothing to look up, and the keys go stale (a later fuse with cells keys afresh)
        m._voxel, (table_keys, table_rows) = (0.0, 0.0), new_table(16)
    cos_thr = float(np.cos(np.deg2rad(cfg.angle_deg)))
    blocks = _merge_blocks(m.blocks_in_view(K, R, t), m._oldest, -(-n // BLOCK), int(k), int(cfg.dormant_frames),
                           bool(cfg.remove_dormant)) if index else np.arange(-(-n // BLOCK))
    merged, considered, dormant, outliers, mixed, nrem, scanned, nt = _merge_pass(
        m._pos, m._nrm, m._w, m._last, m._tp, m._geom, m._key, m._fsum, m._calls, m._touched, n,
        R, t, float(K.f), float(K.cx), float(K.cy), w, h,
        V, N, TP, G, float(cfg.d_thr), cos_thr, stable, int(cfg.dormant_frames), int(k), bool(cfg.remove_dormant),
        bool(cfg.remove_outliers), used, remove, blocks, m._lo, m._hi, m._oldest, table_keys, table_rows)
    size, binned, dropped, fresh, mixed_added, nt = _add_pass(
        m._pos, m._nrm, m._w, m._last, m._tp, m._geom, m._key, m._born, m._serial, m._fsum,
        m._calls, m._touched, nt, n, R, t, V, N, TP, G, used, int(k), m._lo, m._hi, m._oldest, stable,
        1.0 / cfg.voxel if cfg.voxel > 0 else 0.0, 1.0 / max(cfg.voxel, cfg.d_thr), cos_thr, table_keys, table_rows, w)
    _apply_samples(m._pos, m._nrm, m._w, m._last, m._tp, m._fsum, m._touched, nt, int(k), m._lo, m._hi,
                   m._oldest, stable)
    m._table_used += int(fresh) if cfg.voxel > 0 else 0
    added = size - n
    m._n = _remove_pass(m._pos, m._nrm, m._w, m._last, m._tp, m._geom, m._key, m._born, size, remove, nrem, m._lo,
                        m._hi, m._oldest, stable, table_keys, table_rows)
    m._stable = stable
    m._serial += added
    m._unsorted += added + nrem     # appended rows, and at most nrem rows moved into holes
    if m.sort_share is not None and m._unsorted > m.sort_share * len(m):
        m.sort_spatially()
    return FusionStats(int(merged), int(added), int(nrem), int(dormant), int(outliers), int(considered),
                       int(mixed + mixed_added), len(m), int(scanned), int(binned), int(dropped))


def compression_ratio(map_size: int, frames: int, width: int, height: int) -> float:
    """``map_size / (frames · width · height)``: the map against concatenated frames. The homework's
    8.87 % is 1,362,143 / (200 · 320 · 240), i.e. at the downsampled resolution (against 640x480 it
    is 2.22 %)."""
    for name, value in (("map_size", map_size), ("frames", frames), ("width", width), ("height", height)):
        value = int(value) if isinstance(value, np.integer) else value
        check_number(value, f"compression_ratio: {name}", integer=True, lo=0 if name == "map_size" else 1)
    return map_size / (frames * width * height)


def warm_fusion() -> None:
    """Compile or load the fusion and surface kernels on a 4x3 frame, so no real frame waits."""
    from ...kernels import warm
    from ...models.camera import Intrinsics
    from ...models.depth_frame import normal_map, vertex_map
    from .surface import warm_surface

    K = Intrinsics(4, 3, 3.0, 1.5, 1.0)
    depth = np.full((3, 4), 2.0)
    V = vertex_map(depth, K)
    frame = DepthFrame(K, depth, V, normal_map(V), V.copy(), np.zeros((3, 4), np.int64), np.eye(3), np.zeros(3))
    pmap, cfg = PointMap(), FusionConfig(dormant_frames=1, stable_weight=10)
    warm([lambda: [fuse(pmap, frame, np.eye(3), np.zeros(3), k, cfg) for k in range(3)], warm_surface],
         "fusion kernels", expect_s=10)
