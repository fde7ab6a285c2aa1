"""The model rendered into the view: KinectFusion's predicted vertex and normal maps, for a point map.

Frame-to-model ICP registers the new frame to the fused map. Projecting every map point in every
ICP iteration (the homework's ``find_projective_correspondence`` over the whole map) costs
O(map) an iteration, and the map grows with the run (73 000 -> 180 000 points over 60 crates
frames). KinectFusion (Newcombe et al. 2011) instead renders the model ONCE per frame into the
camera at the predicted pose and associates against that image; for a point map (Keller et al.
2013, "Real-time 3D reconstruction in dynamic scenes using point-based fusion") rendering is a
splat with a z-buffer. Here each map point ``p`` is taken into the predicted camera
``(R, t)`` (camera-to-world), ``p_c = Rᵀ (p − t)``, and projected to its nearest pixel

    u = ⌊f x/z + cx + ½⌋,   v = ⌊f y/z + cy + ½⌋,      j = v W + u,

(the projective associator's rounding). Which of the points landing on pixel ``j`` (with ``z > 0``)
the pixel shows is Keller et al.'s rule: of those within ``band`` behind the nearest (the same
surface: the band is fusion's merge distance ``fusion.d_thr``), the most confident (highest
weight, the number of measurements averaged into it), ties to the point added first (its
``born`` serial, so the choice does not depend on the map's row order, ``map_order``):

    z_min[j] = min_{i → j} z_i,   index[j] = argmax_{i → j, z_i ≤ z_min[j] + band} (w_i, −born_i),

−1 where no point lands. Plain nearest-wins is biased: where two unmerged points of one surface
share a pixel (a surface seen again from a new pose adds its unmatched pixels as new points), the
nearer is the one whose noise pulled it towards the camera (by 0.56 σ for two), so the whole
prediction sits in front of the surface, and ICP against it drew the camera back: on the
``dense_ci`` suite (crates, 10 frames) frame-to-model ATE 4.6 mm (projective) and 3.3 mm (kdtree)
against 0.9 and 1.0 mm for the whole map (1.2 and 1.3 mm with this rule, and 0.95 against 5.5 mm
for the whole map over 100 crates frames). Choosing by weight and index does not look at the noise
within the band, and a merged point is an average, the best estimate of its surface.

The chosen points, in raster order, are ICP's source set: at most one point per pixel, so each ICP
iteration touches at most ``W · H`` source points whatever the map's size, and a point hidden
behind a nearer surface of the model, or outside the view, is not a source at all. The splat
itself is two compiled passes per frame over the map's blocks whose bounding box meets the view
frustum (``PointMap.blocks_in_view``: the map's index, ``fusion``), a few arithmetic operations a
point and no per-iteration work; a block wholly outside the frustum has no point that lands on a
pixel, so skipping it changes nothing (``index=False`` visits every point, the same prediction). ICP then moves the camera from the predicted pose: the association stays
projective, pixel to pixel (a point shown on pixel j of the prediction lands on pixel j of the
new frame when the pose is unchanged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...models.camera import Intrinsics
from .fusion import BLOCK, PointMap, pixel_of


@njit(cache=True)
def splat_kernel(pos, weights, born, n, blocks, block, R, t, f, cx, cy, width, height, band, zmin, zbuf, index, rows,
                 pixels, depths):
    """The splat of the points of ``blocks`` (ascending ids of runs of ``block`` rows of
    ``pos[:n]``; module docstring) into ``zmin`` (nearest depth), ``zbuf`` (the shown point's depth)
    and ``index`` (W·H each; filled with inf, inf, −1) in place; returns (the points in front of the
    camera that landed in the image, the points visited). Of equal weights the point born first
    (lower ``born``) is shown. The first pass keeps each landed point's
    (row, pixel, z) in ``rows``, ``pixels``, ``depths`` (room for every visited point), so the
    second reads them in the same order instead of projecting every point again."""
    landed = scanned = 0
    for b in blocks:
        for i in range(b * block, min(n, (b + 1) * block)):
            j, z = pixel_of(pos, i, R, t, f, cx, cy, width, height)
            if j >= 0:
                rows[landed], pixels[landed], depths[landed] = i, j, z
                landed += 1
                if z < zmin[j]:
                    zmin[j] = z
        scanned += max(0, min(n, (b + 1) * block) - b * block)
    for c in range(landed):
        i, j, z = rows[c], pixels[c], depths[c]
        if z <= zmin[j] + band:
            s = index[j]
            if s < 0 or weights[i] > weights[s] or (weights[i] == weights[s] and born[i] < born[s]):
                index[j] = i      # of equal weights the one seen first, whatever the rows' order
                zbuf[j] = z
    return landed, scanned


@njit(cache=True)
def gather_rows(rows, pos, nrm, tp, geom):
    """``(pos[rows], nrm[rows], tp[rows], geom[rows])`` in one compiled pass: the shown points lie
    scattered over the map, and numpy's four fancy-indexing passes cost four rounds of cache misses."""
    n = len(rows)
    p, q, r, g = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, np.int64)
    for k in range(n):
        i = rows[k]
        for a in range(3):
            p[k, a], q[k, a], r[k, a] = pos[i, a], nrm[i, a], tp[i, a]
        g[k] = geom[i]
    return p, q, r, g


@dataclass
class Prediction:
    """The model seen from a predicted pose: ``index`` (H, W) int64 map index of the point each
    pixel shows (−1: none), ``depth`` (H, W) its camera z (inf: none), ``landed`` the map points
    that fell in the image (hidden ones included), ``scanned`` the map points the splat visited
    (those of the blocks in view; the whole map without the index)."""

    index: np.ndarray
    depth: np.ndarray
    landed: int
    scanned: int = 0

    @property
    def source(self) -> np.ndarray:
        """Map indices of the visible points, one per covered pixel, in raster order."""
        flat = self.index.reshape(-1)
        return flat[flat >= 0]


class Splatter:
    """Renders a point map into one camera's image (``predict``), reusing its z-buffer and index
    map from frame to frame (a fresh 77k-pixel array per frame costs its page faults)."""

    def __init__(self, K: Intrinsics, band: float = 0.05) -> None:
        self.K, self.band = K, float(band)
        self._zmin = np.empty(K.width * K.height)
        self._zbuf = np.empty(K.width * K.height)
        self._index = np.empty(K.width * K.height, np.int64)
        self._rows, self._pixels, self._depths = np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)

    def predict(self, positions: np.ndarray, weights: np.ndarray, R: np.ndarray, t: np.ndarray) -> Prediction:
        """The point each pixel shows (module docstring: the most confident within ``band`` of the
        nearest) of the world ``positions`` (n, 3) with ``weights`` (n,), seen from the
        camera-to-world pose ``(R, t)``; every point is visited."""
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        w = np.ascontiguousarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != (len(pos),):
            raise ValueError(f"predict: {len(pos)} positions but {w.shape} weights")
        return self._splat(pos, w, np.arange(len(pos)), len(pos), np.zeros(1, np.int64), max(len(pos), 1), R, t)

    def predict_map(self, pmap: PointMap, R: np.ndarray, t: np.ndarray, index: bool = True) -> Prediction:
        """``predict`` of the map's points, visiting only its blocks in view (``index``; False: every
        point, the same prediction)."""
        blocks = pmap.blocks_in_view(self.K, R, t) if index else np.arange(-(-len(pmap) // BLOCK))
        return self._splat(pmap._pos, pmap._w, pmap._born, len(pmap), blocks, BLOCK, R, t)

    def shown_rows(self, pmap: PointMap, R: np.ndarray, t: np.ndarray, index: bool = True) -> tuple[np.ndarray, int]:
        """``(predict_map(...).source, predict_map(...).scanned)`` without copying the image-sized
        index and depth maps out of the work space (what frame-to-model tracking needs)."""
        blocks = pmap.blocks_in_view(self.K, R, t) if index else np.arange(-(-len(pmap) // BLOCK))
        _, scanned = self._splat_kernel(pmap._pos, pmap._w, pmap._born, len(pmap), blocks, BLOCK, R, t)
        return self._index[self._index >= 0], scanned

    def _splat(self, pos, w, born, n, blocks, block, R, t) -> Prediction:
        landed, scanned = self._splat_kernel(pos, w, born, n, blocks, block, R, t)
        shape = (self.K.height, self.K.width)
        return Prediction(self._index.reshape(shape).copy(), self._zbuf.reshape(shape).copy(), landed, scanned)

    def _splat_kernel(self, pos, w, born, n, blocks, block, R, t) -> tuple[int, int]:
        """``splat_kernel`` into this splatter's work space: (points landed, points visited)."""
        K = self.K
        if len(self._rows) < n:     # the landed points' work space, grown (doubling) with the map
            size = max(n, 2 * len(self._rows))
            self._rows, self._pixels, self._depths = np.empty(size, np.int64), np.empty(size, np.int64), np.empty(size)
        self._zmin.fill(np.inf)
        self._zbuf.fill(np.inf)
        self._index.fill(-1)
        landed, scanned = splat_kernel(pos, w, born, n, blocks, block, np.ascontiguousarray(R, dtype=np.float64),
                                       np.ascontiguousarray(t, dtype=np.float64).reshape(3), float(K.f),
                                       float(K.cx), float(K.cy), K.width, K.height, self.band, self._zmin,
                                       self._zbuf, self._index, self._rows, self._pixels, self._depths)
        return int(landed), int(scanned)


def predict(positions: np.ndarray, weights: np.ndarray, K: Intrinsics, R: np.ndarray, t: np.ndarray,
            band: float = 0.05) -> Prediction:
    """The splat of ``positions`` (weights ``weights``) into camera ``K`` at pose ``(R, t)`` (``Splatter``)."""
    return Splatter(K, band).predict(positions, weights, R, t)
