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
weight, the number of measurements averaged into it), ties to the lower map index:

    z_min[j] = min_{i → j} z_i,   index[j] = argmax_{i → j, z_i ≤ z_min[j] + band} (w_i, −i),

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
itself is two compiled passes over the map per frame (a few arithmetic operations a point, no
per-iteration work). ICP then moves the camera from the predicted pose: the association stays
projective, pixel to pixel (a point shown on pixel j of the prediction lands on pixel j of the
new frame when the pose is unchanged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...models.camera import Intrinsics


@njit(cache=True)
def _pixel(pos, i, R, t, f, cx, cy, width, height):
    """(flat pixel, z) of point ``i`` seen from ``(R, t)``; pixel −1 when behind the camera or
    outside the image (NaN included)."""
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


@njit(cache=True)
def splat_kernel(pos, weights, n, R, t, f, cx, cy, width, height, band, zmin, zbuf, index):
    """The splat of ``pos[:n]`` (module docstring) into ``zmin`` (nearest depth), ``zbuf`` (the
    shown point's depth) and ``index`` (W·H each; filled with inf, inf, −1) in place; returns the
    number of points in front of the camera that landed in the image."""
    landed = 0
    for i in range(n):
        j, z = _pixel(pos, i, R, t, f, cx, cy, width, height)
        if j >= 0:
            landed += 1
            if z < zmin[j]:
                zmin[j] = z
    for i in range(n):
        j, z = _pixel(pos, i, R, t, f, cx, cy, width, height)
        if j >= 0 and z <= zmin[j] + band and (index[j] < 0 or weights[i] > weights[index[j]]):
            index[j] = i      # strict: of equal weights the lower index (seen first) stays
            zbuf[j] = z
    return landed


@dataclass
class Prediction:
    """The model seen from a predicted pose: ``index`` (H, W) int64 map index of the point each
    pixel shows (−1: none), ``depth`` (H, W) its camera z (inf: none), ``landed`` the map points
    that fell in the image (hidden ones included: the splat's own work)."""

    index: np.ndarray
    depth: np.ndarray
    landed: int

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

    def predict(self, positions: np.ndarray, weights: np.ndarray, R: np.ndarray, t: np.ndarray) -> Prediction:
        """The point each pixel shows (module docstring: the most confident within ``band`` of the
        nearest) of the world ``positions`` (n, 3) with ``weights`` (n,), seen from the
        camera-to-world pose ``(R, t)``."""
        K = self.K
        self._zmin.fill(np.inf)
        self._zbuf.fill(np.inf)
        self._index.fill(-1)
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        w = np.ascontiguousarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != (len(pos),):
            raise ValueError(f"predict: {len(pos)} positions but {w.shape} weights")
        landed = splat_kernel(pos, w, len(pos), np.ascontiguousarray(R, dtype=np.float64),
                              np.ascontiguousarray(t, dtype=np.float64).reshape(3), float(K.f), float(K.cx),
                              float(K.cy), K.width, K.height, self.band, self._zmin, self._zbuf, self._index)
        shape = (K.height, K.width)
        return Prediction(self._index.reshape(shape).copy(), self._zbuf.reshape(shape).copy(), int(landed))


def predict(positions: np.ndarray, weights: np.ndarray, K: Intrinsics, R: np.ndarray, t: np.ndarray,
            band: float = 0.05) -> Prediction:
    """The splat of ``positions`` (weights ``weights``) into camera ``K`` at pose ``(R, t)`` (``Splatter``)."""
    return Splatter(K, band).predict(positions, weights, R, t)
