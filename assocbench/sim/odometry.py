"""Odometry: the true motion between consecutive poses plus noise. The increment from pose k−1 to k
in k−1's frame is ``Δp = R_{k−1}ᵀ (p_k − p_{k−1})``, ``ΔR = R_{k−1}ᵀ R_k``; measured,
``Δp + k σ_t n_p`` and ``ΔR Exp(k σ_r n_θ)``, ``n ~ N(0, I₃)`` (``k``: miscalibration; the
filter is told ``σ``). Each frame's noise has its own seeded generator.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..estimators.base import Motion
from ..estimators.config import EstimatorConfig
from ..models.pinhole import exp_so3
from ..models.range_bearing import wrap
from ..models.se2 import between


def true_increment(R0: np.ndarray, p0: np.ndarray, R1: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """``[Δp, Δθ]`` (6,) taking pose 0 to pose 1, in pose 0's frame (``Δθ = Log(R0ᵀ R1)``)."""
    return np.concatenate([R0.T @ (p1 - p0), Rotation.from_matrix(R0.T @ R1).as_rotvec()])


def odometry(rotations: np.ndarray, positions: np.ndarray, k: int, cfg: EstimatorConfig, seed: int) -> Motion:
    """The measured increment from frame ``k − 1`` to ``k`` and the covariance the filter is told."""
    rng = np.random.default_rng([seed, k, 404])
    inc = true_increment(rotations[k - 1], positions[k - 1], rotations[k], positions[k])
    scale = cfg.odometry_miscalibration
    noise_p = rng.normal(0.0, 1.0, 3) * cfg.odometry_sigma_translation * scale
    noise_theta = rng.normal(0.0, 1.0, 3) * np.deg2rad(cfg.odometry_sigma_rotation) * scale
    dR = exp_so3(inc[3:]) @ exp_so3(noise_theta)
    measured = np.concatenate([inc[:3] + noise_p, Rotation.from_matrix(dR).as_rotvec()])
    return Motion(measured, cfg.odometry_covariance)


def planar_odometry(poses: np.ndarray, k: int, cfg: EstimatorConfig, seed: int) -> Motion:
    """The measured planar increment from ``k − 1`` to ``k``, the true one plus
    ``k_m (σ_t n_x, σ_t n_y, σ_θ n_θ)``, and the covariance the filter is told,
    ``diag(σ_t², σ_t², σ_θ²)``."""
    rng = np.random.default_rng([seed, k, 404])
    sigma = np.array([cfg.odometry_sigma_translation] * 2 + [np.deg2rad(cfg.odometry_sigma_rotation)])
    inc = between(poses[k - 1], poses[k]) + rng.normal(0.0, 1.0, 3) * sigma * cfg.odometry_miscalibration
    inc[2] = wrap(inc[2])
    return Motion(inc, np.diag(sigma ** 2))
