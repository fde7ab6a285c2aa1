"""The lines track's closed-loop estimator at frame 0: EKF localisation on the known map of walls."""

from __future__ import annotations

import numpy as np

from ...belief.config import BeliefConfig, map_mask
from ...belief.planar import planar_pose_covariance
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from .belief import sample_line_pose
from .ekf import NOT_ISAM2, NOT_SLAM, LineEKF


def make_line_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The ``LineEKF`` at frame 0: localisation from the sampled pose with Σ_pose on the mapped
    lines; ``slam`` or ``isam2`` is a ``UserError`` saying what to use."""
    if cfg.name != "ekf":
        raise UserError(NOT_ISAM2)
    if cfg.mode != "localisation":
        raise UserError(NOT_SLAM)
    pose_hat = sample_line_pose(seq.poses[0], belief, np.random.default_rng([seed, 0, 505]))
    ids = np.flatnonzero(map_mask(len(seq.lines), belief, seed))
    return LineEKF(cfg, pose_hat, planar_pose_covariance(belief), seq.lines, seq.segments, seq.segment_line,
                   seq.segment_normal, ids, seq.max_range, seq.fov)
