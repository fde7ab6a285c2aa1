"""The estimators a closed-loop run can use, and how each starts from a sequence and a belief."""

from __future__ import annotations

import numpy as np

from ..belief.camera_belief import BeliefConfig, map_mask, sample_estimate
from ..errors import UserError
from ..sim.sequence import Sequence
from .camera_ekf import CameraEKF
from .config import EstimatorConfig

ESTIMATORS = ("ekf",)


def initial_landmark_covariance(n: int, belief: BeliefConfig) -> np.ndarray:
    """Σ_L = σ_l² I + σ_c² (11ᵀ ⊗ I₃), the map covariance the sampled belief reports (3n, 3n)."""
    cov = belief.sigma_landmark ** 2 * np.eye(3 * n)
    if belief.sigma_common > 0:
        cov += belief.sigma_common ** 2 * np.kron(np.ones((n, n)), np.eye(3))
    return cov


def make_estimator(seq: Sequence, cfg: EstimatorConfig, belief: BeliefConfig, seed: int) -> CameraEKF:
    """The estimator at frame 0.

    ``localisation``: pose and the mapped landmarks (``belief.map_fraction``) start at the open
    loop's sampled estimate of frame 0 (truth plus an error from ``k² Σ``) with Σ reported.
    ``slam``: the pose starts at the true first pose with zero covariance (it fixes the gauge,
    as every SLAM system's first frame does) and the map is empty; frame 0's features make it."""
    if cfg.name not in ESTIMATORS:
        raise UserError(f"unknown estimator {cfg.name!r}: choose one of {', '.join(ESTIMATORS)}")
    R0, p0 = seq.rotations[0], seq.positions[0]
    if cfg.mode == "slam":
        return CameraEKF(seq.K, cfg, R0, p0, np.zeros((6, 6)), np.zeros((0, 3)), np.zeros((0, 3)),
                         np.zeros(0, np.int64), belief.max_view_angle)
    rng = np.random.default_rng([seed, 0, 505])
    R_hat, p_hat, l_hat = sample_estimate(R0, p0, seq.landmarks, belief, rng)
    ids = np.flatnonzero(map_mask(len(seq.landmarks), belief, seed))
    P = np.zeros((6 + 3 * len(ids),) * 2)
    P[:6, :6] = belief.pose_covariance
    P[6:, 6:] = initial_landmark_covariance(len(ids), belief)
    return CameraEKF(seq.K, cfg, R_hat, p_hat, P, l_hat[ids], seq.normals[ids], ids, belief.max_view_angle)
