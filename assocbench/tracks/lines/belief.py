"""Belief of the lines track (open loop): the pose estimate is the truth plus an error drawn from
Σ_pose; the map of wall lines is exact (the architect's plan: EKF localisation). Candidates are the
mapped lines the estimate expects to see (``candidate_lines``), predicted ``ẑ_j = h(x̂, m_j)``
(``models.polar_line``) with ``P = H Σ_pose Hᵀ`` (one shared pose error: rank ≤ 3). Measurements are
the extracted lines plus ``clutter`` uniform over α × r.
"""

from __future__ import annotations

import numpy as np

from ...association.problem import Problem
from ...association.truth import FrameTruth
from ...belief.config import BeliefConfig, map_mask, true_association, with_clutter_labels
from ...belief.planar import (
    RANGE_MARGIN,
    clutter_detections,
    nominal_noise,
    planar_pose_covariance,
    sample_planar_estimate,
)
from ...models.polar_line import ANGULAR, jacobians, predict


def facing(pose: np.ndarray, segments: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(S,) whether each face's front holds the pose, ``(p_xy − a)·n > 0`` (a wall is seen from its
    front only)."""
    return np.einsum("sk,sk->s", np.asarray(pose[:2], dtype=np.float64) - segments[:, 0], normals) > 0


def _clip_positive(lo: np.ndarray, hi: np.ndarray, f0: np.ndarray, f1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The part of ``[lo, hi]`` where the linear ``f(t) = f0 + (f1 − f0) t`` is ≥ 0 (empty: lo > hi)."""
    slope = f1 - f0
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(slope != 0, -f0 / slope, 0.0)
    lo = np.where(slope > 0, np.maximum(lo, root), lo)
    hi = np.where(slope < 0, np.minimum(hi, root), hi)
    never = (slope == 0) & (f0 < 0)
    return np.where(never, 1.0, lo), np.where(never, 0.0, hi)


def _in_range_interval(rel: np.ndarray, d: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """``t ∈ [0, 1]`` with ``rel + t d`` within ``reach`` of the origin: the roots of
    ``|rel + t d|² = reach²`` clipped (empty: lo > hi)."""
    a = np.einsum("sk,sk->s", d, d)
    b = np.einsum("sk,sk->s", rel, d)
    c = np.einsum("sk,sk->s", rel, rel) - reach ** 2
    disc = b * b - a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = (-b - root) / a, (-b + root) / a
    lo, hi = np.maximum(np.nan_to_num(lo, nan=0.0), 0.0), np.minimum(np.nan_to_num(hi, nan=1.0), 1.0)
    empty = (disc < 0) | ((a == 0) & (c > 0))
    return np.where(empty, 1.0, lo), np.where(empty, 0.0, hi)


def segments_in_view(pose: np.ndarray, segments: np.ndarray, max_range: float, fov: float) -> np.ndarray:
    """(S,) whether some point of each segment lies within ``RANGE_MARGIN · max_range`` and
    ``fov/2`` of the heading (clipped to the disc, then the wedge)."""
    rel = segments[:, 0] - np.asarray(pose[:2], dtype=np.float64)
    d = segments[:, 1] - segments[:, 0]
    lo, hi = _in_range_interval(rel, d, RANGE_MARGIN * max_range)
    if fov >= 2 * np.pi:
        return lo <= hi
    half, th = fov / 2, float(pose[2])
    # inward normals of the wedge's two boundary rays (headings θ ± fov/2)
    n1 = np.array([-np.sin(th - half), np.cos(th - half)])
    n2 = np.array([np.sin(th + half), -np.cos(th + half)])
    f = [(rel @ n, (rel + d) @ n) for n in (n1, n2)]
    if half <= np.pi / 2:
        for f0, f1 in f:
            lo, hi = _clip_positive(lo, hi, f0, f1)
        return lo <= hi
    return np.logical_or.reduce([np.less_equal(*_clip_positive(lo, hi, f0, f1)) for f0, f1 in f])


def candidate_lines(pose: np.ndarray, segments: np.ndarray, segment_line: np.ndarray, segment_normal: np.ndarray,
                    n_lines: int, max_range: float, fov: float) -> np.ndarray:
    """(K,) map lines with a segment facing ``pose`` with a point in range and field of view (2π:
    all round)."""
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    ok = facing(pose, segments, np.asarray(segment_normal, dtype=np.float64).reshape(-1, 2))
    ok &= segments_in_view(pose, segments, max_range, fov)
    out = np.zeros(n_lines, dtype=bool)
    out[np.asarray(segment_line, dtype=np.int64)[ok]] = True
    return out


def pose_prediction_covariance(H_pose: np.ndarray, Sigma_pose: np.ndarray) -> np.ndarray:
    """``P = H Σ_pose Hᵀ`` (2n, 2n), ``H`` the stacked ``H_pose`` (n, 2, 3): rank ≤ 3, cross terms
    kept."""
    H = H_pose.reshape(-1, 3)
    P = H @ Sigma_pose @ H.T
    return 0.5 * (P + P.T)


def clutter_lines(rng: np.random.Generator, count: int, R: np.ndarray, max_range: float,
                  fov: float) -> tuple[np.ndarray, np.ndarray]:
    """``count`` false lines ``(α, r)`` uniform over ``[−fov/2, fov/2] × [0, max_range]`` with noise
    ``R``: the posts' clutter draw, columns swapped."""
    z, cR = clutter_detections(rng, count, R, max_range, fov)
    return z[:, ::-1].copy(), cR


def sample_line_pose(pose: np.ndarray, cfg: BeliefConfig, rng: np.random.Generator) -> np.ndarray:
    """The pose estimate: truth plus an error from ``k² Σ_pose`` (the map is exact)."""
    return sample_planar_estimate(pose, np.zeros((0, 2)), cfg, rng)[0]


def make_line_problem(seq, frame: int, cfg: BeliefConfig, seed: int) -> tuple[Problem, FrameTruth]:
    """The open-loop problem and truth of one lines frame (``seq``: a ``LineSequence``)."""
    rng = np.random.default_rng([seed, frame, 101])
    pose_hat = sample_line_pose(seq.poses[frame], cfg, rng)
    in_map = map_mask(len(seq.lines), cfg, seed)
    cand = np.flatnonzero(in_map & candidate_lines(pose_hat, seq.segments, seq.segment_line, seq.segment_normal,
                                                   len(seq.lines), seq.max_range, seq.fov))
    H_pose, _ = jacobians(pose_hat, seq.lines[cand])
    z, R = seq.z[frame].reshape(-1, 2), seq.R[frame].reshape(-1, 2, 2)
    cz, cR = clutter_lines(rng, cfg.clutter, nominal_noise(R, seq.nominal_R), seq.max_range, seq.fov)
    labels = with_clutter_labels(np.asarray(seq.labels[frame], dtype=np.int64), cfg.clutter, in_map)
    problem = Problem(z=np.vstack([z, cz]), R=np.concatenate([R, cR]), zhat=predict(pose_hat, seq.lines[cand]),
                      P=pose_prediction_covariance(H_pose, planar_pose_covariance(cfg)), landmark_ids=cand,
                      volume=seq.max_range * seq.fov, angular=ANGULAR)
    return problem, FrameTruth(labels, true_association(labels, cand), seq.visible[frame][cand])
