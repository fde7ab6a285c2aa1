"""The camera track's closed-loop estimator at frame 0 (EKF-SLAM or localisation)."""

from __future__ import annotations

import numpy as np

from ...belief.config import BeliefConfig, map_mask, sample_estimate
from ...belief.planar import map_covariance
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from .ekf import CameraEKF


def make_camera_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The camera EKF at frame 0: ``localisation`` starts the pose and mapped landmarks at the open
    loop's sampled estimate with Σ reported; ``slam`` at the true first pose with zero covariance
    (the gauge) and an empty map."""
    if cfg.name != "ekf":
        raise UserError(f"estimator.name {cfg.name} serves the planar track only; the camera track's estimator is ekf")
    R0, p0 = seq.rotations[0], seq.positions[0]
    if cfg.mode == "slam":
        return CameraEKF(seq.K, cfg, R0, p0, np.zeros((6, 6)), np.zeros((0, 3)), np.zeros((0, 3)),
                         np.zeros(0, np.int64), belief.max_view_angle)
    rng = np.random.default_rng([seed, 0, 505])
    R_hat, p_hat, l_hat = sample_estimate(R0, p0, seq.landmarks, belief, rng)
    ids = np.flatnonzero(map_mask(len(seq.landmarks), belief, seed))
    P = np.zeros((6 + 3 * len(ids),) * 2)
    P[:6, :6] = belief.pose_covariance
    P[6:, 6:] = map_covariance(len(ids), belief, dim=3)
    return CameraEKF(seq.K, cfg, R_hat, p_hat, P, l_hat[ids], seq.normals[ids], ids, belief.max_view_angle)
