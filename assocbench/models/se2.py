"""Planar poses ``(x, y, θ)``: ``compose`` and ``between`` (GTSAM's ``Pose2`` convention)."""

from __future__ import annotations

import numpy as np

from .range_bearing import wrap


def compose(pose: np.ndarray, increment: np.ndarray) -> np.ndarray:
    """``pose ⊕ Δ = (x + cos θ Δx − sin θ Δy, y + sin θ Δx + cos θ Δy, wrap(θ + Δθ))``."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.array([pose[0] + c * increment[0] - s * increment[1], pose[1] + s * increment[0] + c * increment[1],
                     float(wrap(pose[2] + increment[2]))])


def between(pose0: np.ndarray, pose1: np.ndarray) -> np.ndarray:
    """``Δ`` with ``pose0 ⊕ Δ = pose1``: ``(R(θ₀)ᵀ (p₁ − p₀), wrap(θ₁ − θ₀))``."""
    c, s = np.cos(pose0[2]), np.sin(pose0[2])
    d = np.asarray(pose1[:2], dtype=np.float64) - pose0[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], float(wrap(pose1[2] - pose0[2]))])


def rot2(theta: float) -> np.ndarray:
    """``R(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]`` (2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def rz(theta: np.ndarray | float) -> np.ndarray:
    """Headings as rotations about z, ``Rz(θ)``: (3, 3) or (N, 3, 3), for code writing 3-D poses."""
    t = np.asarray(theta, dtype=np.float64)
    out = np.zeros(t.shape + (3, 3))
    c, s = np.cos(t), np.sin(t)
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out
