"""KD-tree data association: each source point's nearest valid vertex of the frame in 3-D.

The tree (``scipy.spatial.cKDTree``) holds the frame's valid vertices in its CAMERA frame, so it
is built once per frame, whatever the pose guess; it is cached on the associator for the last
frame seen (by identity: ICP's iterations on one frame share it; a frame changed in place after a
call is not noticed). A source point ``p`` is queried at ``p_c = Rᵀ (p − t)`` with an upper bound
the largest gate in the frame, ``gate(max depth)`` (a farther neighbour fails the distance filter
anyway, and the bound prunes the search).

First filter (``considered``, the visible points), the homework's as in the projective method:
``z > 0``, the nearest pixel of the projection inside the image, and the point not hidden behind
that pixel's measured surface (``z ≤ d + gate(d)``, ``base``). Without the view test a source
point just outside the frame's view would pair with the nearest vertex on the image border (same
surface, but a point the frame never saw: 4 % of the pairs were such in a 2 deg / 5 cm
frame-to-frame step of the synthetic room). The valid-pixel part of that filter is the tree's (it
holds valid vertices only), so a point projecting onto a missing pixel is considered and may
still pair with a vertex nearby. The distance filter (the gate of the paired vertex's depth) and
the angle filter are then applied in world coordinates (``base.world_filters``), like the
projective ones.
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
    """(mask, flat pixel) of camera-frame points with ``z > 0`` whose nearest pixel
    ``⌊f x/z + c + ½⌋`` lies in the image (NaN: outside); the pixel ``v·W + u`` is −1 outside."""
    K, (h, w) = frame.K, frame.depth.shape
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(K.f * pc[:, 0] / z + K.cx + 0.5)
        v = np.floor(K.f * pc[:, 1] / z + K.cy + 0.5)
        inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    col, row = np.where(inside, u, 0).astype(np.int64), np.where(inside, v, 0).astype(np.int64)
    return inside, np.where(inside, row * w + col, -1)


def visible(pc: np.ndarray, frame: DepthFrame, assoc: DenseAssociator) -> np.ndarray:
    """Mask of camera-frame points in view (``in_view``) and not hidden behind their pixel's
    measured surface: ``z ≤ d + gate(d)`` where the pixel has a depth ``d`` (a missing pixel
    hides nothing)."""
    inside, pix = in_view(pc, frame)
    d = frame.depth.reshape(-1)[np.where(inside, pix, 0)]
    with np.errstate(invalid="ignore"):
        hidden = pc[:, 2] > d + assoc.gate(d)    # NaN depth: False
    return inside & ~hidden
