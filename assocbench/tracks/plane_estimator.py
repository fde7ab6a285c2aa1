"""The closed-loop estimator at frame 0 of a robot in the plane with range-bearing point landmarks
(EKF-SLAM, or GTSAM iSAM2): the planar track's, and a recorded log's."""

from __future__ import annotations

import numpy as np

from ..belief.config import BeliefConfig, map_mask
from ..belief.planar import map_covariance, planar_pose_covariance, sample_planar_estimate
from ..estimators.config import EstimatorConfig
from ..estimators.planar_ekf import PlanarEKF


def planar_estimator_class(name: str) -> type:
    """``ekf``: ``PlanarEKF``; ``isam2``: ``PlanarISAM2`` (gtsam is an extra: imported only when
    iSAM2 is asked for)."""
    if name == "isam2":
        from ..estimators.planar_isam2 import PlanarISAM2

        return PlanarISAM2
    return PlanarEKF


def make_planar_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int, cls: type | None = None):
    """The planar estimator (``cls``, default ``planar_estimator_class(cfg.name)``) at frame 0:
    ``slam`` from the first pose with zero covariance and no map; ``localisation`` from the sampled
    pose and mapped landmarks with Σ = blockdiag(Σ_pose, Σ_L)."""
    cls = cls or planar_estimator_class(cfg.name)
    if cfg.mode == "slam":
        return cls(cfg, seq.poses[0], np.zeros((3, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), seq.max_range, seq.fov)
    rng = np.random.default_rng([seed, 0, 505])
    pose_hat, map_hat = sample_planar_estimate(seq.poses[0], seq.landmarks, belief, rng)
    ids = np.flatnonzero(map_mask(len(seq.landmarks), belief, seed))
    P = np.zeros((3 + 2 * len(ids),) * 2)
    P[:3, :3] = planar_pose_covariance(belief)
    P[3:, 3:] = map_covariance(len(ids), belief)
    return cls(cfg, pose_hat, P, map_hat[ids], ids, seq.max_range, seq.fov)
