"""A synthetic planar world for the estimators' tests (no MuJoCo): posts on a grid, a robot on a
circle, range-bearing measurements with known noise, and odometry in the planar convention (``x' = x ⊕ Δ``:
the increment is in the previous pose's frame)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assocbench.estimators.base import FrameData, Motion
from assocbench.models.range_bearing import predict, wrap
from assocbench.models.se2 import between, compose  # noqa: F401  (compose: for the tests that import it here)


@dataclass
class SynthWorld:
    posts: np.ndarray          # (L, 2)
    poses: np.ndarray          # (N, 3) true poses
    frames: list[FrameData]    # measurements of frame k (range, bearing), R
    labels: list[np.ndarray]   # post index of each measurement
    motions: list[Motion]      # motions[k]: odometry from k−1 to k (motions[0] unused)
    max_range: float
    fov: float


def synth_world(steps: int = 500, seed: int = 0, radius: float = 6.0, laps: float = 2.0, max_range: float = 5.0,
                sigma_r: float = 0.02, sigma_b_deg: float = 0.5, sigma_t: float = 0.01,
                sigma_h_deg: float = 0.3, spacing: float = 2.0) -> SynthWorld:
    """``steps`` poses on a circle of ``radius`` (``laps`` times round, heading along it), posts on
    a grid of ``spacing`` over the circle's square (minus those within 0.5 m of the path), each
    post within ``max_range`` measured with ``R = diag(σ_r², σ_b²)`` (360° field of view), and
    odometry with ``Q = diag(σ_t², σ_t², σ_h²)`` per step."""
    rng = np.random.default_rng([seed, 99])
    g = np.arange(-radius - 2, radius + 2.01, spacing)
    posts = np.array([[x, y] for x in g for y in g])
    posts = posts[np.abs(np.linalg.norm(posts, axis=1) - radius) > 0.5]
    t = np.linspace(0, 2 * np.pi * laps, steps, endpoint=False)
    poses = np.column_stack([radius * np.cos(t), radius * np.sin(t), wrap(t + np.pi / 2)])
    R = np.diag([sigma_r ** 2, np.deg2rad(sigma_b_deg) ** 2])
    Q = np.diag([sigma_t ** 2, sigma_t ** 2, np.deg2rad(sigma_h_deg) ** 2])
    frames, labels, motions = [], [], [Motion(np.zeros(3), Q)]
    for k in range(steps):
        zhat = predict(poses[k], posts)
        seen = np.flatnonzero(zhat[:, 0] < max_range)
        z = zhat[seen] + rng.multivariate_normal(np.zeros(2), R, len(seen))
        z[:, 1] = wrap(z[:, 1])
        frames.append(FrameData(z, np.repeat(R[None], len(seen), axis=0)))
        labels.append(seen)
        if k:
            motions.append(Motion(between(poses[k - 1], poses[k]) + rng.multivariate_normal(np.zeros(3), Q), Q))
    return SynthWorld(posts, poses, frames, labels, motions, max_range, 2 * np.pi)


def true_association(problem_ids: np.ndarray, tie: dict[int, int], labels: np.ndarray) -> np.ndarray:
    """The true association of a problem: for each candidate (map id, tied to post ``tie[id]``) the
    measurement of that post, or -1. A post with several map entries (a duplicate) pairs with the
    oldest (lowest map id) only, as ``harness.loop_truth`` does."""
    where = {int(p): i for i, p in enumerate(labels)}
    out = np.full(len(problem_ids), -1, dtype=np.int64)
    for j in np.argsort(problem_ids, kind="stable"):
        out[j] = where.pop(tie.get(int(problem_ids[j]), -2), -1)
    return out
