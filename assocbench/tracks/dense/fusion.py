"""Point-based fusion of depth frames into a point map (the dense-SLAM homework, section 3 and its bonus).

Given a frame with vertex map ``V`` and normal map ``N`` (camera frame) and its pose ``(R, t)``
(camera-to-world), every map point ``p`` (world) with normal ``n_p`` and weight ``w`` is projected
into the frame, ``p_c = Rᵀ (p − t)``, ``(u, v) = round(f x/z + c)``, and filtered as the homework does:

* pass 1: ``z > 0``, ``0 ≤ u < W``, ``0 ≤ v < H``, and the pixel valid (finite depth ``> 0`` and normal);
* pass 2: ``q = R V[v,u] + t`` and ``n_q = R N[v,u]`` with ``|p − q| < d_thr`` and
  ``angle(n_p, n_q) < angle_deg`` (``n_p · n_q > cos angle_deg``).

A point that passes is **merged** (weighted average; the frame's vertex has weight 1)::

    p   ← (w p + R q + t) / (w + 1)
    n_p ← (w n_p + R n_q) / (w + 1),   n_p ← n_p / ‖n_p‖
    w   ← w + 1,   last_seen ← k

Several map points may merge with one pixel (the homework's rule; a pixel is one measurement
each of them gets). With ``voxel: 0`` (the homework's rule) every valid pixel that no map point
merged with is **added** as a new point (``R q + t``, ``R n_q``, weight 1): the map then grows with
every new viewpoint, because a surface seen again has pixels between the old points (93k -> 249k
points in view over 200 crates frames). By default (``voxel`` 1 cm) such a pixel first looks up
the **cell** of its point and normal (``voxel_table``): when a map point holds it, the pixel merges
into that point (the frame's samples of one point are averaged and count once: weight + 1 a
frame), and only a pixel in a free cell is added, so the map keeps one point per cell and its
size levels off once the scene is seen. The merges are applied once the frame is read: each point
sums its samples of the frame (its projective pixel and the pixels of its cell), and one pass
merges their mean with weight 1 (``_apply_samples``; a new point has weight 0, so it becomes its
samples' mean); the gates compare the samples with the map as it was before the frame. Summing
instead of updating the point at every sample (9 additions, not 18 divisions and a square root:
a crates frame has 31 000 such extra pixels) took fusion from 14.5 to 10.6 ms a frame (120 crates
frames at true poses, one core), the map the same to 0.4 % (fused noise |p − true| median 0.79 mm,
p95 4.7 mm; 84 310 against 84 031 points). Then (the bonus) points are **removed**:

* dormant: ``w < stable_weight`` and not merged for ``dormant_frames`` frames (``k − last_seen ≥
  dormant_frames``), in view or not;
* outliers: ``w < stable_weight`` and seen through: the point projects onto a pixel whose measured
  depth lies more than ``d_thr`` behind it (``z < depth[v,u] − d_thr``): the sensor sees a surface
  beyond, so nothing is there. Stable points are kept (a surface seen many times outvotes one frame).

Truth rides along: each point's ``true_points`` is averaged with the pixel's true point with the
same weights as its position (so ``p − true_point`` is the weighted mean of the fused noise), and
its ``geom`` stays the geom of the pixels it fused while they agree, ``MIXED_GEOM`` once two
differ (a point averaged across an edge has no single true surface).

All three steps are compiled loops (numba): one pass over the map projects, filters, takes the
samples and marks removals; one pass over the pixels takes the cells' samples and adds; one over
the touched points merges; removal fills the holes below the new size with
the surviving points from above it (O(removed), not O(map)), so point order is not kept. The map
keeps spare capacity (doubling), so adding is not a copy of the whole map per frame.

**The map's index** (``index``): the points are kept in blocks of ``BLOCK`` consecutive rows, each
with a bounding box ``[lo, hi]`` and a lower bound ``oldest`` of the ``last_seen`` of its unstable
points. A block's points lie close together because the map is kept in spatial order: points are
appended in raster order (a run of neighbouring pixels of one frame), and once the rows added or
moved since reach a tenth of the map the whole map is sorted by cell (``map_order``: a later frame's few
hundred new points are scattered over the image, so unsorted blocks would span the room). Sorting
moves rows and changes nothing else. The merge pass visits only the blocks whose box meets the view frustum
(``blocks_in_view``) and, for the dormant rule, those that may hold a dormant point
(``k − oldest ≥ dormant_frames``); every other block provably has no point that projects into the
image and none that turns dormant, so skipping it changes nothing: the map, its order and the
statistics are those of the whole-map pass bit for bit (``index=False`` runs it; the tests compare
them). A skipped block's points do not move, so its box and bound stay true; a visited block's are
recomputed, an added or moved-in point widens its block's. Out-of-view blocks are visited only while
they hold unstable points about to turn dormant, so the work per frame follows what is in view
(``FusionStats.scanned``), plus one box test per block (1/``BLOCK`` of the map).
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
# arrays: the cell pass adds samples to points at random rows, and each array was a cache miss
# more (fusion 13.8 -> 12.4 ms a crates frame with the voxel table's slots packed too:
# benchmarks/dense_fusion_ab.py)
SUM_COLUMNS, COUNT, CALL = 11, 9, 10


@dataclass(frozen=True)
class FusionStats:
    """What one ``fuse`` call did: map points merged, pixels added as points, points removed
    (``dormant`` + ``outliers``), map points that passed pass 1 (``considered``), points whose
    truth became ``MIXED_GEOM`` in this call, the map size after, and the map points the merge pass
    visited (``scanned``: the blocks in view or holding a point about to turn dormant; the whole
    map without the index), the unmerged pixels merged into the point holding their cell
    (``binned``) and those dropped because that point's normal failed the angle gate (``dropped``;
    both 0 without cells, ``fusion.voxel: 0``)."""

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
    """A growing set of surfel-like points in world coordinates: ``positions`` (n, 3), unit
    ``normals`` (n, 3), ``weights`` (n,) (1 + merges), ``last_seen`` (n,) (the frame index of the
    last merge or the addition), and truth for scoring only: ``true_points`` (n, 3) (NaN: unknown)
    and ``geom`` (n,) (``NO_GEOM`` unknown, ``MIXED_GEOM`` mixed), and ``born`` (n,), the serial of
    the point's addition (a point's identity: rows move, by removal and by ``sort_spatially``, which
    ``fuse`` calls past ``sort_share`` of unsorted rows; None never sorts). The properties are views of the
    first n rows of buffers with spare capacity; ``fuse`` changes them in place and keeps the index
    of blocks (module docstring) in step, so they are to be read, not written (they stay writable
    arrays because the compiled kernels that read them, e.g. the surface distance, would otherwise
    compile a second, read-only version; a map built with ``from_arrays`` is indexed afresh)."""

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
        """Buffers of ``cap`` rows holding the current points; written through once (``fill``) so
        their pages are mapped here, when the map grows, not inside a later frame's fusion."""
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
        """Make the voxel table hold the cells of size ``voxel`` (``thick`` along the normal's
        dominant axis) of the current points with room for ``extra`` more keys below half its size:
        the points keyed afresh when the cells changed (a map built from arrays, or fused before
        with other cells), the table rebuilt when full."""
        if (voxel, thick) != self._voxel:
            keys_of(self._pos, self._nrm, self._n, 1.0 / voxel, 1.0 / thick, self._key)
            self._voxel, self._table_used = (voxel, thick), len(self._table_keys)   # forces the rebuild below
        if 2 * (self._table_used + extra) > len(self._table_keys):
            # the power of two above 2 (n + extra): at most half full once the frame's keys are in. Twice
            # that (a quarter full) made the add pass's probes miss the caches more: 16 MB of table at
            # 100k points, its pass 4.5-4.6 against 3.9-4.2 ms a crates frame
            size = 1 << max(4, int(2 * (self._n + extra)).bit_length())
            self._table_keys, self._table_rows = new_table(size)
            self._table_used = table_build(self._table_keys, self._table_rows, self._key, self._n)

    def blocks_in_view(self, K, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Ascending ids of the blocks whose box meets the view frustum of camera ``K`` at the
        camera-to-world pose ``(R, t)`` (``frustum_blocks``): any point that projects into the image
        lies in one of them."""
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
        """Put the rows in spatial order (``map_order``: by the Morton code of their cell, stably),
        every field moving with its point, the voxel table and the blocks' boxes renewed. Changes no
        result, only which rows share a block."""
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
    """Recompute the box and ``oldest`` (the least ``last`` of a point with ``w < stable_w``) of
    each block in ``blocks`` from its points (NaN positions widen no box: they project nowhere)."""
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


@njit(cache=True, inline="always")   # inlined: a call passing seven arrays counted their references,
def _widen(lo, hi, oldest, i, pos, w, last, stable_w):   # 60 ns of a binned pixel's 240 (1.9 ms a frame)
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
    """Whether block ``b``'s box lies wholly on the negative side of the plane ``a · p_c = 0``
    through the camera centre (``a`` in camera coordinates, ``p_c = Rᵀ (p − t)``): the largest of
    ``(R a) · (p − t)`` over the box, centre term plus half-extents, is below zero by more than
    rounding (a relative 1e-9 margin, so a point on the boundary is never culled)."""
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
    """Ascending ids of the blocks ``< blocks`` not wholly outside one of the five planes a point
    that lands on a pixel satisfies (``z > 0``; ``0 ≤ f x/z + cx + ½ < W``, i.e.
    ``f x + (cx + ½) z ≥ 0`` and ``(W − cx − ½) z − f x > 0``; the same for ``v``). A block with no
    point (empty box) is outside."""
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
    """Ascending ids of the blocks the merge pass visits: those in view (ascending ``in_view``) and,
    when dormant points are dropped, those that may hold one (``k − oldest ≥ dormant_frames``)."""
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
    """(flat pixel, z) of point ``i`` seen from ``(R, t)``: ``p_c = Rᵀ (p − t)``, the nearest pixel of
    ``(f x / z + cx, f y / z + cy)``; pixel −1 when behind the camera or outside the image (NaN
    included). The one projection of the splat and of fusion's merge."""
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
    """Add the sample ``q``, ``m`` (world; truth ``TP[j]``, ``G[j]``) to map point ``i``'s sums of
    the ``fuse`` call ``call`` (``fsum`` columns 0-8: Σq, Σm, Σtruth; ``COUNT``: how many); the call's first
    sample starts them and lists the point in ``touched[nt]``. ``_apply_samples`` merges them once
    the frame is read. Returns (the number of touched points, 1 when the point's truth turned
    ``MIXED_GEOM``)."""
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
    """The homework's merge of frame ``k`` into each touched point, its samples' mean
    ``(q̄, m̄, t̄) = Σ / c`` (c = ``fsum[i, COUNT]``) taken as ONE measurement of weight 1:

        p ← (w p + q̄) / (w + 1),   n ← (w n + m̄) / (w + 1),  n ← n / ‖n‖,
        true ← (w true + t̄) / (w + 1),   w ← w + 1,   last_seen ← k

    (a cell holds several pixels of a frame, and pixels of one frame share its pose and its smoothed
    normals: counting each would let one frame outvote many). A point added in this call has
    ``w = 0``: it becomes its samples' mean with weight 1. Each moved point widens its block."""
    for r in range(nt):     # reciprocals: 3 divisions a point, not 15 (fusion 10.6 against 11.2-12.0 ms a crates frame)
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
    """One pass over the points of ``blocks`` (ascending; every block: the whole map): project, the
    homework's filters, the sample taken for the merge (``_take_sample``; the points' positions and
    normals stay those of the frame before until ``_apply_samples``), and removals
    marked in ascending order into ``remove`` (and their cells freed in the voxel table at once, so
    a sample in one adds a fresh point); the visited blocks' boxes and ``oldest`` are computed anew
    on the way (``_index_blocks``'s result, without a second pass over the points).
    Returns (merged, considered, dormant, outliers, mixed, removals, scanned, touched points)."""
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
    """``box`` (lo x, y, z, hi x, y, z) widened to hold point ``i`` (a NaN coordinate widens nothing),
    as ``_index_blocks`` computes it."""
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    return (min(box[0], x) if x == x else box[0], min(box[1], y) if y == y else box[1],
            min(box[2], z) if z == z else box[2], max(box[3], x) if x == x else box[3],
            max(box[4], y) if y == y else box[4], max(box[5], z) if z == z else box[5])


@njit(cache=True)
def _add_pass(pos, nrm, w, last, tp, geom, key, born, serial, fsum, call, touched, nt, n, R, t, V, N, TP, G,
              used, k, lo, hi, oldest, stable_w, inv_voxel, inv_thick, cos_thr, table_keys, table_rows, width):
    """Every valid pixel no map point merged with (raster order): with cells (``inv_voxel`` > 0,
    ``voxel_table``) one whose cell a point holds is a sample of that point (``_take_sample``: the
    samples of one frame count once) when their normals pass the angle gate, and is dropped when
    not; any other is appended with weight 0 as its own first sample, taking its cell, and widens
    its block's box (a block's first row starts it afresh). Returns (new size, samples merged into their cell's point, samples dropped, table
    slots newly used, points whose truth turned mixed, touched points)."""
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
    """Remove the points ``remove[:nrem]`` (ascending; already gone from the voxel table): the holes
    below the new size m = n − nrem are filled, in ascending order, with the surviving points at
    m..n−1 in ascending order (each widening the hole's block, its cell told of the move)."""
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
    """The frame's maps flattened to pixels j = v W + u, in the dtypes the kernels take (the depth
    is the vertices' z, ``vertex_map``)."""
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
    """Fuse ``frame`` seen from the camera-to-world pose ``(R, t)`` (the estimate; the frame's own
    ``R``, ``t`` are truth and unused) as frame number ``k`` into ``pmap`` in place: merge, add,
    remove (module docstring). ``index=False`` visits every map point (the same result, the
    whole-map baseline). Returns what it did."""
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
    """``map_size / (frames · width · height)``: the map against naive concatenation of every frame
    at ``width`` x ``height``. Which resolution to pass is the caller's choice, and it matters by the
    downsample factor squared: the homework's 8.87 % is 1,362,143 / (200 · 320 · 240), its frames'
    resolution *after* downsampling 640x480 by 2 (its text says "no down-sampling", but the 15,360,000
    points it divides by are 200 · 320 · 240); against 640x480 the same map is 2.22 %."""
    for name, value in (("map_size", map_size), ("frames", frames), ("width", width), ("height", height)):
        value = int(value) if isinstance(value, np.integer) else value
        check_number(value, f"compression_ratio: {name}", integer=True, lo=0 if name == "map_size" else 1)
    return map_size / (frames * width * height)


def warm_fusion() -> None:
    """Compile (or load from numba's cache) the fusion kernels and the surface-distance kernel on
    a 4x3 frame, with the note ``kernels.warm`` prints while they compile, so the first real frame
    is not the one that waits."""
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
