"""KD-tree data association: each source point's nearest valid vertex in 3-D. The tree holds the
frame's valid vertices in its CAMERA frame, so it is built once per frame whatever the guess (cached
by the frame's identity), and queried at ``p_c = Rᵀ (p − t)`` within ``gate(max depth)``. First
filter as the projective method's (in front, in the image, not hidden), so a point outside the view
does not pair with a border vertex; a point over a missing pixel may still pair nearby. Distance and
angle filters follow (``base.world_filters``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ...models.depth_frame import DepthFrame
from .base import DenseAssociator, Pairs, checked_inputs, flat_maps, world_filters


class KdTreeAssociator(DenseAssociator):
    """Nearest valid vertex in 3-D (cKDTree, built once per frame), then the homework's filters."""

    name = "kdtree"
    summary = "nearest valid vertex in 3-D (cKDTree, built once per frame); distance and normal-angle filters"

    def __post_init__(self) -> None:
        super().__post_init__()
        self._cache: tuple | None = None   # (frame, tree, pixel of each tree point)

    def tree(self, frame: DepthFrame) -> tuple[cKDTree, np.ndarray]:
        """(tree, pixel index of each tree point) of ``frame``'s valid vertices (cached)."""
        if self._cache is None or self._cache[0] is not frame:
            _, V, _ = flat_maps(frame)
            pixel = np.flatnonzero(frame.valid.reshape(-1))
            self._cache = (frame, cKDTree(V[pixel]), pixel)
        return self._cache[1:]

    def associate(self, points, normals, frame: DepthFrame, R, t) -> Pairs:
        p, n, R, t = checked_inputs(points, normals, frame, R, t)
        tree, pixel = self.tree(frame)
        pc = (p - t) @ R                                       # Rᵀ (p − t), row-wise
        depth, V, N = flat_maps(frame)
        cand = np.flatnonzero(visible(pc, frame, self))
        if len(cand) == 0 or len(pixel) == 0:
            return Pairs.empty(len(cand))
        bound = float(self.gate(np.max(depth[pixel])))            # the largest gate in the frame
        _, nn = tree.query(pc[cand], k=1, distance_upper_bound=bound, workers=1)
        found = nn < len(pixel)                                # a miss returns index len(pixel)
        src, pix = cand[found], pixel[nn[found]]
        keep = world_filters(p, n, V, N, src, pix, R, t, self.gate(depth[pix]), self.cos_thr)
        return Pairs(src[keep].astype(np.int64), pix[keep].astype(np.int64), len(cand))


def in_view(pc: np.ndarray, frame: DepthFrame) -> tuple[np.ndarray, np.ndarray]:
    """(mask, flat pixel) of camera-frame points with ``z > 0`` whose nearest pixel lies in the
    image; pixel −1 outside (NaN too)."""
    K, (h, w) = frame.K, frame.depth.shape
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(K.f * pc[:, 0] / z + K.cx + 0.5)
        v = np.floor(K.f * pc[:, 1] / z + K.cy + 0.5)
        inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    col, row = np.where(inside, u, 0).astype(np.int64), np.where(inside, v, 0).astype(np.int64)
    return inside, np.where(inside, row * w + col, -1)


def visible(pc: np.ndarray, frame: DepthFrame, assoc: DenseAssociator) -> np.ndarray:
    """Camera-frame points in view and not behind their pixel's depth ``d`` by more than ``gate(d)``
    (a missing pixel hides nothing)."""
    inside, pix = in_view(pc, frame)
    d = frame.depth.reshape(-1)[np.where(inside, pix, 0)]
    with np.errstate(invalid="ignore"):
        hidden = pc[:, 2] > d + assoc.gate(d)    # NaN depth: False
    return inside & ~hidden
