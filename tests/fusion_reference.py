"""The same point-based fusion as ``tracks.dense.fusion.fuse`` in plain vectorised numpy (the way
the homework's skeleton writes it: masks, fancy indexing, ``np.concatenate``): the tests check the
compiled kernels against it and ``benchmarks/fusion_rate.py`` times both."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assocbench.models.depth_frame import DepthFrame
from assocbench.tracks.dense.fusion import MIXED_GEOM
from assocbench.tracks.dense.settings import FusionConfig


@dataclass
class NumpyMap:
    positions: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    last_seen: np.ndarray
    true_points: np.ndarray
    geom: np.ndarray

    @classmethod
    def of(cls, pmap) -> NumpyMap:
        """A copy of a ``PointMap`` (or another ``NumpyMap``)."""
        return cls(*(np.array(getattr(pmap, a)) for a in ("positions", "normals", "weights", "last_seen",
                                                           "true_points", "geom")))

    def __len__(self) -> int:
        return len(self.weights)


def fuse_numpy(m: NumpyMap, frame: DepthFrame, R: np.ndarray, t: np.ndarray, k: int,
               cfg: FusionConfig) -> tuple[int, int, int]:
    """Filter, merge, add, remove (in that order, the kernels' rules); returns (merged, added, removed)."""
    K, (h, w) = frame.K, frame.depth.shape
    depth, V = frame.depth.reshape(-1), frame.vertices.reshape(-1, 3)
    N, TP, G = frame.normals.reshape(-1, 3), frame.true_points.reshape(-1, 3), frame.geom.reshape(-1)
    pc = (m.positions - t) @ R                                   # Rᵀ (p − t), row-wise
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(K.f * pc[:, 0] / z + K.cx + 0.5)
        v = np.floor(K.f * pc[:, 1] / z + K.cy + 0.5)
    inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)   # pass 1
    idx = np.flatnonzero(inside)
    j = (v[idx] * w + u[idx]).astype(np.int64)
    d = depth[j]
    ok = (d > 0) & np.isfinite(N[j, 0])
    q, nq = V[j] @ R.T + t, N[j] @ R.T
    close = np.linalg.norm(m.positions[idx] - q, axis=1) < cfg.d_thr            # pass 2
    aligned = np.einsum("ij,ij->i", m.normals[idx], nq) > np.cos(np.deg2rad(cfg.angle_deg))
    assoc = ok & close & aligned
    a, ja = idx[assoc], j[assoc]
    wa = m.weights[a][:, None]
    m.positions[a] = (wa * m.positions[a] + q[assoc]) / (wa + 1)
    nrm = (wa * m.normals[a] + nq[assoc]) / (wa + 1)
    m.normals[a] = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    m.true_points[a] = (wa * m.true_points[a] + TP[ja]) / (wa + 1)
    m.geom[a] = np.where((m.geom[a] >= 0) & (m.geom[a] != G[ja]), MIXED_GEOM, m.geom[a])
    m.weights[a] += 1
    m.last_seen[a] = k

    unstable = m.weights < cfg.stable_weight
    drop = np.zeros(len(m), bool)
    if cfg.remove_outliers:
        seen_through = ~assoc & (d > 0) & (z[idx] < d - cfg.d_thr)
        drop[idx[seen_through]] = True
    if cfg.remove_dormant:
        drop |= (k - m.last_seen >= cfg.dormant_frames)
    drop &= unstable
    drop[a] = False

    used = np.zeros(h * w, bool)
    used[ja] = True
    new = np.flatnonzero(~used & (depth > 0) & np.isfinite(N[:, 0]))
    m.positions = np.concatenate([m.positions, V[new] @ R.T + t])
    m.normals = np.concatenate([m.normals, N[new] @ R.T])
    m.weights = np.concatenate([m.weights, np.ones(len(new))])
    m.last_seen = np.concatenate([m.last_seen, np.full(len(new), k, np.int64)])
    m.true_points = np.concatenate([m.true_points, TP[new]])
    m.geom = np.concatenate([m.geom, G[new].astype(np.int64)])

    remove = np.flatnonzero(drop)                              # the kernels' hole filling
    size = len(m) - len(remove)
    holes = remove[remove < size]
    fill = np.setdiff1d(np.arange(size, len(m)), remove)
    for name in ("positions", "normals", "weights", "last_seen", "true_points", "geom"):
        arr = getattr(m, name)
        arr[holes] = arr[fill]
        setattr(m, name, arr[:size])
    return len(a), len(new), len(remove)
