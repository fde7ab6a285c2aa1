"""Posts from a lidar scan: clusters, a circle of the known radius fitted to each, and the range and
bearing of its centre with a first-order covariance.

**Segmentation.** Returns in beam order break wherever consecutive hit points lie more than ``gap``
apart (full circle: the last cluster joins the first). Two points of one post are never farther
apart than ``2ρ``, so ``gap = 2ρ`` never splits a post. A cluster under ``min_points`` or wider than
``2ρ + 6σ_r`` is no post.

**Circle fit** (Gauss-Newton on the centre ``c``, radius ``ρ`` known): ``e_i = |p_i − c| − ρ``,
``∂e_i/∂c = −n_iᵀ``, ``n_i = (p_i − c)/|p_i − c|``; range noise moves ``p_i`` along its beam
``u_i``, so σ_i = σ_r |n_i·u_i| (clamped at ``COS_FLOOR``). Each step solves
``(Jᵀ W J) δ = −Jᵀ W e`` (``W = diag(1/σ_i²)``) by a 2×2 Cholesky factor;
``cov(c) = (Jᵀ W J)⁻¹ = L⁻ᵀ L⁻¹``. The start is the cluster's mean pushed back by ``ρ``. A fit with
residual RMS over ``max_rms`` (clutter, walls, box corners) or a centre not behind its points is
rejected.

**Measurement.** ``z = (r, φ) = (|c|, atan2(c_y, c_x))``, ``R = G cov(c) Gᵀ``,
``G = [[c_x/r, c_y/r], [−c_y/r², c_x/r²]]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sim.scan import Scan
from .settings import PostDetectorConfig

COS_FLOOR = 0.3      # smallest |n·u| used for a residual's σ (a beam 72.5° off the surface normal)
GN_STEPS = 6         # Gauss-Newton steps: from the pushed-back mean a post's fit converges in 3-4
CONVERGED = 1e-4     # m: a fit whose last step is longer has not converged (3-point clutter arcs)


@dataclass
class Detections:
    """One frame's posts: ``z`` (m, 2) range and bearing of the centres, ``R`` (m, 2, 2), ``beams``
    each was fitted to."""

    z: np.ndarray
    R: np.ndarray
    beams: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.z)

    @staticmethod
    def empty() -> Detections:
        return Detections(np.zeros((0, 2)), np.zeros((0, 2, 2)), [])


def segment(points: np.ndarray, gap: float, full_circle: bool) -> tuple[np.ndarray, np.ndarray]:
    """Clusters of consecutive hit points in beam order, split where ``|p_i − p_{i−1}| > gap`` (full
    circle: read from the first break, so a cluster across beam 0 stays whole). Returns the reading
    order and each point's cluster label (non-decreasing)."""
    n = len(points)
    order = np.arange(n)
    if n < 2:
        return order, np.zeros(n, int)
    if full_circle:
        jump = np.linalg.norm(points - np.roll(points, 1, axis=0), axis=1) > gap   # before point i
        if jump.any():
            order = np.roll(order, -int(np.argmax(jump)))
    breaks = np.linalg.norm(np.diff(points[order], axis=0), axis=1) > gap
    return order, np.concatenate([[0], np.cumsum(breaks)])


def fit_circles(p: np.ndarray, starts: np.ndarray, radius: float) -> tuple[np.ndarray, tuple, np.ndarray]:
    """Gauss-Newton circles of ``radius`` through ``p``, clusters contiguous from ``starts``, all at
    once. Returns centres (k, 2), the Cholesky factor ``(l11, l21, l22)`` of ``Σ w n nᵀ``
    (``= σ_r² JᵀWJ``) and the residual RMS (``inf`` if not converged)."""
    count = np.diff(np.append(starts, len(p)))
    lab = np.repeat(np.arange(len(starts)), count)
    mean = np.add.reduceat(p, starts, axis=0) / count[:, None]
    c = mean * (1 + radius / np.linalg.norm(mean, axis=1))[:, None]
    u = p / np.sqrt(np.einsum("ij,ij->i", p, p))[:, None]
    terms = np.empty((len(p), 5))
    for _ in range(GN_STEPS):
        d = p - c[lab]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        n = d / dist[:, None]
        e = dist - radius
        w = 1.0 / np.maximum(np.abs(np.einsum("ij,ij->i", n, u)), COS_FLOOR) ** 2
        wn = w[:, None] * n
        terms[:, 0:2] = wn * n
        terms[:, 2] = wn[:, 0] * n[:, 1]
        terms[:, 3:5] = wn * e[:, None]
        axx, ayy, axy, bx, by = np.add.reduceat(terms, starts, axis=0).T
        chol = chol2(axx, axy, ayy)
        step = solve_chol2(*chol, bx, by)   # J = −nᵀ: δ = (Σ w n nᵀ)⁻¹ Σ w n e
        c = c + step
    rms = np.sqrt(np.add.reduceat(e ** 2, starts) / count)
    rms[np.linalg.norm(step, axis=1) > CONVERGED] = np.inf   # still moving: no circle of this radius fits
    return c, chol, rms


def chol2(a11: np.ndarray, a21: np.ndarray, a22: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cholesky ``L = [[l11, 0], [l21, l22]]`` of symmetric 2×2 matrices, elementwise (``l22`` 0
    where singular)."""
    l11 = np.sqrt(np.maximum(a11, 1e-300))
    l21 = a21 / l11
    l22 = np.sqrt(np.maximum(a22 - l21 ** 2, 1e-300))
    return l11, l21, l22


def solve_chol2(l11, l21, l22, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """``x = (L Lᵀ)⁻¹ b`` (k, 2) by a forward and a back substitution."""
    y1 = b1 / l11
    y2 = (b2 - l21 * y1) / l22
    x2 = y2 / l22
    return np.column_stack([(y1 - l21 * x2) / l11, x2])


def inverse_chol2(l11, l21, l22) -> np.ndarray:
    """``(L Lᵀ)⁻¹ = L⁻ᵀ L⁻¹`` (k, 2, 2)."""
    i11, i22 = 1 / l11, 1 / l22
    i21 = -l21 * i11 * i22             # L⁻¹ = [[i11, 0], [i21, i22]]
    out = np.empty((len(l11), 2, 2))
    out[:, 0, 0] = i11 ** 2 + i21 ** 2
    out[:, 0, 1] = out[:, 1, 0] = i21 * i22
    out[:, 1, 1] = i22 ** 2
    return out


def range_bearing(c: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``z = (|c|, atan2(c_y, c_x))`` (k, 2) and ``R = G cov Gᵀ`` (k, 2, 2)."""
    r = np.linalg.norm(c, axis=1)
    G = np.empty((len(c), 2, 2))
    G[:, 0, 0], G[:, 0, 1] = c[:, 0] / r, c[:, 1] / r
    G[:, 1, 0], G[:, 1, 1] = -c[:, 1] / r ** 2, c[:, 0] / r ** 2
    return np.column_stack([r, np.arctan2(c[:, 1], c[:, 0])]), G @ cov @ G.transpose(0, 2, 1)


def detect_posts(scan: Scan, radius: float, sigma_range: float, cfg: PostDetectorConfig) -> Detections:
    """Posts of radius ``radius`` in ``scan`` (see the module docstring), in beam order."""
    beam = np.flatnonzero(np.isfinite(scan.ranges))
    pts = scan.points()[beam]
    order, lab = segment(pts, cfg.gap if cfg.gap is not None else 2 * radius, scan.full_circle)
    beam, pts = beam[order], pts[order]
    if not len(lab):
        return Detections.empty()
    starts = np.flatnonzero(np.diff(lab, prepend=-1))
    ends = np.append(starts[1:], len(lab)) - 1
    width = np.linalg.norm(pts[ends] - pts[starts], axis=1)
    keep = (ends - starts + 1 >= cfg.min_points) & (width <= 2 * radius + 6 * sigma_range)
    if not keep.any():
        return Detections.empty()
    sel = keep[lab]
    kept_starts = np.cumsum(np.append(0, (ends - starts + 1)[keep]))
    c, chol, rms = fit_circles(pts[sel], kept_starts[:-1], radius)
    mean_sq = np.add.reduceat(np.einsum("ij,ij->i", pts[sel], pts[sel]), kept_starts[:-1]) / np.diff(kept_starts)
    good = (rms <= cfg.max_rms) & (np.einsum("ij,ij->i", c, c) > mean_sq) & np.isfinite(c).all(axis=1)
    z, R = range_bearing(c[good], sigma_range ** 2 * inverse_chol2(*(x[good] for x in chol)))
    groups = np.split(beam[sel], kept_starts[1:-1])   # contiguous, in cluster order
    return Detections(z, R, [g for g, ok in zip(groups, good) if ok])


def label_detections(det: Detections, scan: Scan, post_geom_ids: np.ndarray, min_share: float = 0.8) -> np.ndarray:
    """Truth of each detection: the post at least ``min_share`` (> 1/2) of its beams hit (the median
    of its sorted post indices), else −1."""
    if not len(det):
        return np.zeros(0, int)
    post_of = np.full(max(int(scan.geom.max()), int(post_geom_ids.max())) + 2, -1)
    post_of[post_geom_ids] = np.arange(len(post_geom_ids))
    size = np.array([len(b) for b in det.beams])
    group = np.repeat(np.arange(len(det)), size)
    idx = post_of[scan.geom[np.concatenate(det.beams)]]     # geom −1 reads the last entry: −1
    idx = idx[np.lexsort((idx, group))]
    starts = np.cumsum(size) - size
    median = idx[starts + size // 2]
    share = np.add.reduceat((idx == median[group]).astype(float), starts) / size
    return np.where((share >= min_share) & (median >= 0), median, -1)
