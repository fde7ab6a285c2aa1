"""Lines ``(α, r)`` from a lidar scan, with their covariance, by one of three methods (lecture 24).

**Breakpoints**: the returns ``p_i = ρ_i (cos β_i, sin β_i)``, in beam order, split where
``|p_j − p_i| > d₀ + min(ρ_i, ρ_j) Δφ / sin λ`` (Borges & Aldon's adaptive breakpoint: ``Δφ`` the
beam step, ``λ`` the shallowest wall-to-beam angle, ``d₀`` the noise margin). Over a full circle the
points are read from a breakpoint, so a wall across the seam stays one chain; no breakpoint at all
is a closed loop, read from its farthest point.

**Methods** (``LineExtractorConfig.method``):

* ``polar``: one weighted polar fit per chain (the baseline: a chain turning a corner fails).
* ``split_merge``: split at the point farthest from the chord while beyond ``split_distance``; trim
  end points beyond ``TRIM_SIGMAS`` σ; drop segments under ``min_points``; merge collinear segments,
  most compatible first, when ``χ² = vᵀ(Σ_i + Σ_j)⁻¹v ≤ merge_chi2`` (``v = (Δα, Δr)``), their ends
  within ``merge_gap`` and the refit within ``split_distance``.
* ``ransac``: ``ransac_iterations`` 2-point hypotheses, most inliers within ``inlier_distance``
  wins, refitted, cut at breakpoints; pieces with ``min_points`` become lines, until too few points
  or ``max_lines``.

All end with the weighted polar fit (``polar_fit``), dropping fits beyond ``max_rms`` and segments
under ``min_length``. Null thresholds scale with σ: ``breakpoint_distance`` 10σ, ``split_distance``
6σ, ``inlier_distance`` 3σ, ``max_rms`` 2σ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...errors import UserError
from ...models.range_bearing import wrap
from ...sim.scan import Scan
from ...validation import check_number
from .polar_fit import group_fits, line_from_sums, point_terms
from .settings import LineExtractorConfig

TRIM_SIGMAS = 3.0        # an end point farther than this from its segment's fit is trimmed
TRIM_ROUNDS = 4          # ends trimmed per segment at most (a corner costs one or two)


@dataclass(frozen=True)
class _Thresholds:
    """The config's distances resolved for one range noise σ (m)."""

    sigma: float
    breakpoint: float
    slope: float          # Δφ / sin λ: the range-proportional breakpoint term per metre of range
    split: float
    rms: float
    inlier: float


def _thresholds(cfg: LineExtractorConfig, sigma: float, step: float) -> _Thresholds:
    def pick(value, k):
        return value if value is not None else k * sigma
    return _Thresholds(sigma, pick(cfg.breakpoint_distance, 10), step / np.sin(np.deg2rad(cfg.breakpoint_angle_deg)),
                       pick(cfg.split_distance, 6), pick(cfg.max_rms, 2), pick(cfg.inlier_distance, 3))


@dataclass
class LineDetections:
    """One scan's lines: ``z`` (m, 2) ``(α, r)``, α ∈ [−π, π), r ≥ 0; ``R`` (m, 2, 2); ``endpoints``
    (m, 2, 2); ``beams`` the inlier beams."""

    z: np.ndarray
    R: np.ndarray
    endpoints: np.ndarray
    beams: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.z)

    @staticmethod
    def empty() -> LineDetections:
        return LineDetections(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), [])


@dataclass
class _Points:
    """A scan's returns in reading order (see ``_chains``): beam index, range, bearing, point."""

    beam: np.ndarray
    rho: np.ndarray
    beta: np.ndarray
    p: np.ndarray
    terms: np.ndarray     # (n, 6) the fit's per-point terms (uniform weights)
    full_circle: bool

    def take(self, idx: np.ndarray) -> _Points:
        return _Points(self.beam[idx], self.rho[idx], self.beta[idx], self.p[idx], self.terms[idx], self.full_circle)


def _apart(pts: _Points, i: np.ndarray, j: np.ndarray, th: _Thresholds) -> np.ndarray:
    """Breakpoint test between points i and j (bool): ``|p_j − p_i| > d₀ + min(ρ) Δφ / sin λ``."""
    gap = np.linalg.norm(pts.p[j] - pts.p[i], axis=1)
    return gap > th.breakpoint + np.minimum(pts.rho[i], pts.rho[j]) * th.slope


def _breaks(pts: _Points, th: _Thresholds) -> np.ndarray:
    """``brk[i]``: a breakpoint before point i (full circle: point 0's predecessor is the last)."""
    n = len(pts.rho)
    i = np.arange(n)
    brk = _apart(pts, i - 1, i, th)          # i − 1 = −1: the last point (full circle)
    if not pts.full_circle:
        brk[0] = True
    return brk


def _chains(pts: _Points, th: _Thresholds) -> tuple[_Points, np.ndarray, bool]:
    """The points re-read from a breakpoint on (full circle), each chain's start, and whether the
    scan is one closed loop."""
    brk = _breaks(pts, th)
    if not brk.any():
        first = int(np.argmax(pts.rho))
        return pts.take(np.roll(np.arange(len(brk)), -first)), np.zeros(1, int), True
    first = int(np.argmax(brk))
    order = np.roll(np.arange(len(brk)), -first)
    return pts.take(order), np.flatnonzero(brk[order]), False


@njit(cache=True)
def _iepf(p: np.ndarray, bounds: np.ndarray, split: float, smallest: int) -> np.ndarray:
    """Iterative end-point fit of the chains ``p[bounds[c]:bounds[c+1]]``: split at the farthest
    point while beyond ``split``; pieces under ``smallest`` points stay. Returns pieces (k, 2)
    ``[a, b)``; compiled."""
    out = np.empty((len(p), 2), np.int64)
    stack = np.empty((len(p) + 2, 2), np.int64)
    k = 0
    for c in range(len(bounds) - 1):
        top = 0
        stack[0, 0], stack[0, 1] = bounds[c], bounds[c + 1]
        top = 1
        while top:
            top -= 1
            i, j = stack[top, 0], stack[top, 1]
            best, at = -1.0, i
            if j - i >= smallest:
                cx, cy = p[j - 1, 0] - p[i, 0], p[j - 1, 1] - p[i, 1]
                length = np.hypot(cx, cy)
                for q in range(i + 1, j - 1):
                    qx, qy = p[q, 0] - p[i, 0], p[q, 1] - p[i, 1]
                    d = abs(qx * cy - qy * cx) / length if length > 1e-9 else np.hypot(qx, qy)
                    if d > best:
                        best, at = d, q
            if best > split:
                stack[top, 0], stack[top, 1] = at, j          # right piece popped after the left one
                stack[top + 1, 0], stack[top + 1, 1] = i, at
                top += 2
            else:
                out[k, 0], out[k, 1] = i, j
                k += 1
    return out[:k]


def _trim(pts: _Points, cs: np.ndarray, seg: np.ndarray, gate: float, min_points: int) -> np.ndarray:
    """Segments ``[a, b)`` with end points beyond ``gate`` from their fit cut (fits from cumulative
    sums ``cs``), short ones dropped."""
    a, b = seg[:, 0].copy(), seg[:, 1].copy()
    for _ in range(TRIM_ROUNDS):
        keep = b - a >= min_points
        a, b = a[keep], b[keep]
        if not len(a):
            break
        alpha, r, _ = line_from_sums(cs[b] - cs[a])
        da = np.abs(pts.rho[a] * np.cos(pts.beta[a] - alpha) - r) > gate
        db = np.abs(pts.rho[b - 1] * np.cos(pts.beta[b - 1] - alpha) - r) > gate
        if not (da.any() or db.any()):
            break
        a, b = a + da, b - db
    keep = b - a >= min_points
    return np.column_stack([a[keep], b[keep]])


@dataclass
class _Fits:
    """Fits of groups of points: ``(α, r)``, covariances, RMS and largest orthogonal distance."""

    alpha: np.ndarray
    r: np.ndarray
    cov: np.ndarray
    rms: np.ndarray
    worst: np.ndarray
    ends: np.ndarray      # (k, 2, 2) extreme points along each line, projected on it


def _fit_groups(pts: _Points, groups: list[np.ndarray], sigma: float) -> _Fits:
    """Weighted polar fit (uniform weights: one σ per beam) and covariance of each group."""
    idx = np.concatenate(groups)
    size = np.array([len(g) for g in groups])
    starts = np.cumsum(size) - size
    alpha, r, _ = line_from_sums(np.add.reduceat(pts.terms[idx], starts, axis=0))
    cov, _, st = group_fits(pts.rho[idx], pts.beta[idx], 1.0, sigma ** 2, 0.0, alpha, r, starts)
    n = np.column_stack([np.cos(alpha), np.sin(alpha)])
    tang = np.column_stack([-n[:, 1], n[:, 0]])
    ends = (r[:, None] * n)[:, None, :] + st[:, 2:4, None] * tang[:, None, :]   # extreme points, projected
    return _Fits(alpha, r, cov, st[:, 0], st[:, 1], ends)


def _finish(pts: _Points, groups: list[np.ndarray], th: _Thresholds, cfg: LineExtractorConfig,
            f: _Fits | None = None) -> LineDetections:
    """Final fits of the groups: fit, residual test, length test, in beam order."""
    if f is None:
        groups = [g for g in groups if len(g) >= cfg.min_points]
        if not groups:
            return LineDetections.empty()
        f = _fit_groups(pts, groups, th.sigma)
    if not groups:
        return LineDetections.empty()
    ends = f.ends
    keep = (f.rms <= th.rms) & (np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1) >= cfg.min_length)
    keep &= np.isfinite(f.cov).all(axis=(1, 2))
    beams = [np.sort(pts.beam[g]) for g, k in zip(groups, keep) if k]
    order = np.argsort([b[0] for b in beams], kind="stable")
    z = np.column_stack([f.alpha, f.r])[keep][order]
    return LineDetections(z, f.cov[keep][order], ends[keep][order], [beams[i] for i in order])


def _polar(pts: _Points, th: _Thresholds, cfg: LineExtractorConfig, rng) -> LineDetections:
    pts, starts, _ = _chains(pts, th)
    return _finish(pts, np.split(np.arange(len(pts.rho)), starts[1:]), th, cfg)


def _split_merge(pts: _Points, th: _Thresholds, cfg: LineExtractorConfig, rng) -> LineDetections:
    pts, starts, closed = _chains(pts, th)
    n = len(pts.rho)
    bounds = np.append(starts, n)
    if closed:   # read from the farthest point; the first cut is at the point farthest from it
        k = int(np.argmax(np.linalg.norm(pts.p - pts.p[0], axis=1)))
        bounds = np.array([0, k, n]) if 0 < k < n else bounds
    seg = _iepf(np.ascontiguousarray(pts.p), bounds.astype(np.int64), th.split, max(cfg.min_points, 3))
    cs = np.vstack([np.zeros(6), np.cumsum(pts.terms, axis=0)])
    seg_arr = _trim(pts, cs, seg, TRIM_SIGMAS * th.sigma, cfg.min_points)
    groups = [np.arange(a, b) for a, b in seg_arr]
    if not groups:
        return LineDetections.empty()
    groups, f = _merge(pts, groups, th, cfg)
    return _finish(pts, groups, th, cfg, f)


def _pair_tests(pts: _Points, groups: list[np.ndarray], f: _Fits, th: _Thresholds,
                cfg: LineExtractorConfig) -> np.ndarray:
    """χ² (k, k) of each pair's ``(α, r)`` difference (inf where not mergeable: gap or χ² too large)."""
    k = len(groups)
    v = np.stack([wrap(f.alpha[:, None] - f.alpha[None]), f.r[:, None] - f.r[None]], axis=-1)
    C = f.cov[:, None] + f.cov[None]
    det = C[..., 0, 0] * C[..., 1, 1] - C[..., 0, 1] ** 2
    chi2 = (C[..., 1, 1] * v[..., 0] ** 2 - 2 * C[..., 0, 1] * v[..., 0] * v[..., 1] + C[..., 0, 0] * v[..., 1] ** 2) / det
    ends = f.ends   # (k, 2, 2)
    gap = np.linalg.norm(ends[:, None, :, None] - ends[None, :, None, :], axis=-1).min(axis=(2, 3))
    bad = (chi2 > cfg.merge_chi2) | (gap > cfg.merge_gap) | np.tri(k, dtype=bool)
    return np.where(bad, np.inf, chi2)


def _merge(pts: _Points, groups: list[np.ndarray], th: _Thresholds,
           cfg: LineExtractorConfig) -> tuple[list[np.ndarray], _Fits]:
    """Merge collinear groups, most compatible first, when the refit lies within ``split_distance``
    of every point and ``max_rms``. Returns groups and fits."""
    f = _fit_groups(pts, groups, th.sigma)
    refused: set[tuple[int, int]] = set()
    while len(groups) > 1:
        chi2 = _pair_tests(pts, groups, f, th, cfg)
        for i, j in refused:
            chi2[i, j] = np.inf
        i, j = np.unravel_index(int(np.argmin(chi2)), chi2.shape)
        if not np.isfinite(chi2[i, j]):
            break
        g = np.concatenate([groups[i], groups[j]])
        m = _fit_groups(pts, [g], th.sigma)
        if m.worst[0] > th.split or m.rms[0] > th.rms:
            refused.add((int(i), int(j)))
            continue
        keep = [q for q in range(len(groups)) if q not in (i, j)]
        groups = [groups[q] for q in keep] + [g]
        f = _Fits(*(np.concatenate([getattr(f, a)[keep], getattr(m, a)]) for a in ("alpha", "r", "cov", "rms", "worst", "ends")))
        refused = {(a - (a > i) - (a > j), b - (b > i) - (b > j)) for a, b in refused if i not in (a, b) and j not in (a, b)}
    return groups, f


def _pieces(pts: _Points, idx: np.ndarray, th: _Thresholds) -> list[np.ndarray]:
    """Positions ``idx`` cut at breakpoints (circularly over a full circle)."""
    if len(idx) < 2:
        return [idx]
    brk = _apart(pts, np.roll(idx, 1), idx, th)
    if not pts.full_circle:
        brk[0] = True
    if not brk.any():
        return [idx]
    first = int(np.argmax(brk))
    idx, brk = np.roll(idx, -first), np.roll(brk, -first)
    return np.split(idx, np.flatnonzero(brk)[1:])


def _ransac(pts: _Points, th: _Thresholds, cfg: LineExtractorConfig, rng: np.random.Generator) -> LineDetections:
    left = np.arange(len(pts.rho))
    lines: list[np.ndarray] = []
    for _ in range(2 * cfg.max_lines):
        m = len(left)
        if m < cfg.min_points or len(lines) >= cfg.max_lines:
            break
        P = pts.p[left]
        i = rng.integers(m, size=cfg.ransac_iterations)
        j = (i + rng.integers(1, m, size=cfg.ransac_iterations)) % m
        d = P[j] - P[i]
        nrm = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
        dist = np.abs(P @ nrm.T - np.einsum("ij,ij->i", P[i], nrm))       # (m, hypotheses)
        inl = dist[:, int(np.argmax((dist < th.inlier).sum(axis=0)))] < th.inlier
        alpha, r, _ = line_from_sums(pts.terms[left[inl]].sum(axis=0))   # refit, then re-select the inliers once
        inl = np.abs(pts.rho[left] * np.cos(pts.beta[left] - alpha) - r) < th.inlier
        pieces = _pieces(pts, left[inl], th)
        good = [q for q in pieces if len(q) >= cfg.min_points][: cfg.max_lines - len(lines)]
        lines += good
        gone = np.concatenate(good) if good else left[inl]
        left = np.setdiff1d(left, gone, assume_unique=True)
    return _finish(pts, lines, th, cfg)


_METHODS = {"polar": _polar, "split_merge": _split_merge, "ransac": _ransac}


def extract_lines(scan: Scan, sigma_range: float, cfg: LineExtractorConfig,
                  rng: np.random.Generator | None = None) -> LineDetections:
    """Lines of ``scan`` by ``cfg.method``; ``sigma_range``: the range noise σ (m, > 0) of weights,
    covariances and default thresholds; ``rng``: RANSAC's samples (None: ``default_rng(0)``)."""
    sigma = check_number(sigma_range, "sigma_range (the lidar's range noise)", lo=0, hi=10, lo_open=True)
    ranges, angles = np.asarray(scan.ranges, float), np.asarray(scan.angles, float)
    if ranges.shape != angles.shape or ranges.ndim != 1:
        raise UserError(f"scan ranges and angles must be two (B,) arrays of one length, got {ranges.shape} and {angles.shape}")
    beam = np.flatnonzero(np.isfinite(ranges) & (ranges > 0))
    if len(beam) < cfg.min_points:
        return LineDetections.empty()
    step = float(np.abs(wrap(angles[1] - angles[0]))) if len(angles) > 1 else 0.0
    rho, beta = ranges[beam], angles[beam]
    p = rho[:, None] * np.column_stack([np.cos(beta), np.sin(beta)])
    pts = _Points(beam, rho, beta, p, point_terms(rho, beta, 1.0), bool(scan.full_circle))
    return _METHODS[cfg.method](pts, _thresholds(cfg, sigma, step), cfg, rng if rng is not None else np.random.default_rng(0))


def label_lines(det: LineDetections, beam_labels: np.ndarray, min_share: float) -> np.ndarray:
    """Truth of each line (m,): the map line at least ``min_share`` (> 1/2) of its beams hit
    (``beam_labels``: each beam's map line, −1 none), else −1: the median of its sorted beam labels."""
    share = check_number(min_share, "min_share", lo=0.5, hi=1, lo_open=True)
    if not len(det):
        return np.zeros(0, int)
    labels = np.asarray(beam_labels)
    out = np.full(len(det), -1)
    for k, b in enumerate(det.beams):
        lab = np.sort(labels[b])
        median = lab[len(lab) // 2]
        if median >= 0 and np.mean(lab == median) >= share:
            out[k] = median
    return out
