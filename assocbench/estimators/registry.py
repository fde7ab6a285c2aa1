"""The estimators a closed-loop run can use, and how each starts from a sequence and a belief."""

from __future__ import annotations

import numpy as np

from ..belief.config import BeliefConfig, map_mask
from ..tracks.camera.belief import sample_estimate
from ..tracks.lines.belief import sample_line_pose
from ..belief.planar import map_covariance, planar_pose_covariance, sample_planar_estimate
from ..errors import UserError
from ..tracks.camera.ekf import CameraEKF
from .config import ESTIMATOR_NAMES, EstimatorConfig


def make_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The estimator at frame 0.

    ``localisation``: pose and the mapped landmarks (``belief.map_fraction``) start at the open
    loop's sampled estimate of frame 0 (truth plus an error from ``k² Σ``) with Σ reported.
    ``slam``: the pose starts at the true first pose with zero covariance (it fixes the gauge,
    as every SLAM system's first frame does) and the map is empty; frame 0's features make it."""
    if cfg.name not in ESTIMATOR_NAMES:
        raise UserError(f"unknown estimator {cfg.name!r}: choose one of {', '.join(ESTIMATOR_NAMES)}")
    if getattr(seq, "track", "camera") == "planar":
        return make_planar_estimator(seq, cfg, belief, seed)
    if getattr(seq, "track", "camera") == "lines":
        return make_line_estimator(seq, cfg, belief, seed)
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


def make_planar_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The planar estimator (``ekf``: ``PlanarEKF``; ``isam2``: ``PlanarISAM2``, which needs gtsam) at
    frame 0, started as ``make_estimator`` says, in the plane: ``slam`` from the true first pose
    with zero covariance and no map; ``localisation`` from the sampled pose and mapped posts
    (``belief.map_fraction``) with Σ = blockdiag(Σ_pose, Σ_L) reported."""
    if cfg.name == "isam2":
        from ..tracks.planar.isam2 import PlanarISAM2 as cls
    else:
        from ..tracks.planar.ekf import PlanarEKF as cls
    if cfg.mode == "slam":
        return cls(cfg, seq.poses[0], np.zeros((3, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), seq.max_range, seq.fov)
    pose_hat, map_hat = sample_planar_estimate(seq.poses[0], seq.posts, belief, np.random.default_rng([seed, 0, 505]))
    ids = np.flatnonzero(map_mask(len(seq.posts), belief, seed))
    P = np.zeros((3 + 2 * len(ids),) * 2)
    P[:3, :3] = planar_pose_covariance(belief)
    P[3:, 3:] = map_covariance(len(ids), belief)
    return cls(cfg, pose_hat, P, map_hat[ids], ids, seq.max_range, seq.fov)


def make_line_estimator(seq, cfg: EstimatorConfig, belief: BeliefConfig, seed: int):
    """The lines track's ``LineEKF`` at frame 0: localisation only (the map of walls is known
    exactly), from the sampled pose with Σ_pose reported, on the mapped lines
    (``belief.map_fraction``). ``slam`` or ``isam2`` is a ``UserError`` naming what to use."""
    from ..tracks.lines.ekf import NOT_ISAM2, NOT_SLAM, LineEKF
    if cfg.name != "ekf":
        raise UserError(NOT_ISAM2)
    if cfg.mode != "localisation":
        raise UserError(NOT_SLAM)
    pose_hat = sample_line_pose(seq.poses[0], belief, np.random.default_rng([seed, 0, 505]))
    ids = np.flatnonzero(map_mask(len(seq.lines), belief, seed))
    return LineEKF(cfg, pose_hat, planar_pose_covariance(belief), seq.lines, seq.segments, seq.segment_line,
                   seq.segment_normal, ids, seq.max_range, seq.fov)
