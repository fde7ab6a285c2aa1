"""The model rendered into the view: KinectFusion's predicted maps, for a point map. Projecting the
whole map every ICP iteration costs O(map); KinectFusion (Newcombe et al. 2011) renders the model
once per frame, for a point map a splat with a z-buffer (Keller et al. 2013). A map point goes to
its nearest pixel

    u = ⌊f x/z + cx + ½⌋,   v = ⌊f y/z + cy + ½⌋,      j = v W + u,   (x, y, z) = Rᵀ (p − t),

and the pixel shows the most confident point within ``band`` (fusion's ``d_thr``) of the nearest,
ties to the first born:

    z_min[j] = min_{i → j} z_i,   index[j] = argmax_{i → j, z_i ≤ z_min[j] + band} (w_i, −born_i),

−1 where none lands (nearest-wins would favour points whose noise pulled them towards the camera).
The shown points are ICP's source: at most one per pixel whatever the map's size, hidden points
none. Only the map's blocks in the view frustum are visited (same result as ``index=False``).
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
    """Splat the points of ``blocks`` into ``zmin``, ``zbuf`` and ``index`` (filled with inf, inf,
    −1); returns (points landed, points visited). The first pass keeps each landed point's (row,
    pixel, z) for the second."""
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
    """``(pos[rows], nrm[rows], tp[rows], geom[rows])`` in one pass (one round of cache misses, not
    four)."""
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
    """The model seen from a pose: ``index`` (H, W) map row each pixel shows (−1: none), ``depth``
    (inf: none), ``landed`` and ``scanned`` counts."""

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
    """Renders a point map into one camera's image, reusing its buffers from frame to frame."""

    def __init__(self, K: Intrinsics, band: float = 0.05) -> None:
        self.K, self.band = K, float(band)
        self._zmin = np.empty(K.width * K.height)
        self._zbuf = np.empty(K.width * K.height)
        self._index = np.empty(K.width * K.height, np.int64)
        self._rows, self._pixels, self._depths = np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)

    def predict(self, positions: np.ndarray, weights: np.ndarray, R: np.ndarray, t: np.ndarray) -> Prediction:
        """The point each pixel shows (module docstring) of ``positions`` with ``weights`` seen from
        ``(R, t)``."""
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
        """``predict_map``'s ``source`` and ``scanned`` without copying the image-sized maps."""
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
