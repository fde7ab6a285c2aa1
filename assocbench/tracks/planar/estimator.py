"""The planar track's closed-loop estimator at frame 0 (EKF-SLAM, or GTSAM iSAM2)."""

from __future__ import annotations

import numpy as np

from ...belief.config import BeliefConfig, map_mask
from ...belief.planar import map_covariance, planar_pose_covariance, sample_planar_estimate
from ...estimators.config import EstimatorConfig
from ...estimators.planar_ekf import PlanarEKF


def make_planar_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The planar estimator (``ekf``: ``PlanarEKF``; ``isam2``: ``PlanarISAM2``, which needs gtsam) at
    frame 0, started as ``make_estimator`` says, in the plane: ``slam`` from the true first pose
    with zero covariance and no map; ``localisation`` from the sampled pose and mapped posts
    (``belief.map_fraction``) with Σ = blockdiag(Σ_pose, Σ_L) reported."""
    if cfg.name == "isam2":
        # gtsam is an extra: imported only when iSAM2 is asked for
        from ...estimators.planar_isam2 import PlanarISAM2 as cls
    else:
        cls = PlanarEKF
    if cfg.mode == "slam":
        return cls(cfg, seq.poses[0], np.zeros((3, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), seq.max_range, seq.fov)
    pose_hat, map_hat = sample_planar_estimate(seq.poses[0], seq.posts, belief, np.random.default_rng([seed, 0, 505]))
    ids = np.flatnonzero(map_mask(len(seq.posts), belief, seed))
    P = np.zeros((3 + 2 * len(ids),) * 2)
    P[:3, :3] = planar_pose_covariance(belief)
    P[3:, 3:] = map_covariance(len(ids), belief)
    return cls(cfg, pose_hat, P, map_hat[ids], ids, seq.max_range, seq.fov)
