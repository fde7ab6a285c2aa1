"""The closed loop's sensor of a robot in the plane (``PlanarSensor``): detections plus clutter,
planar odometry, the pose error ``[δx, δy, δθ]``; the lines track's is the same with wall lines
``(α, r)``."""

from __future__ import annotations

import numpy as np

from ..belief.config import BeliefConfig, with_clutter_labels
from ..belief.planar import clutter_detections, nominal_noise
from ..estimators.base import FrameData, Motion
from ..estimators.config import EstimatorConfig
from ..models.range_bearing import pose_error as planar_pose_error
from ..models.se2 import compose
from ..scoring.trajectory import nees_or_nan, pose_columns
from ..sim.odometry import planar_odometry


class PlanarSensor:
    """The planar track: post detections (range, bearing) plus clutter, planar odometry, 3-dof
    pose error ``[δx, δy, δθ]``."""

    nees_dof = 3
    new_landmark_gate = 4.0   # σ: without it a strict gate's misses become duplicates (30 for JCBB on the park)
    clutter = staticmethod(clutter_detections)   # false detections (range, bearing) uniform over the sensor's view

    def __init__(self, seq, belief: BeliefConfig, est: EstimatorConfig, seed: int) -> None:
        self.seq, self.belief, self.est, self.seed = seq, belief, est, seed
        self.dead_reckoning = np.array(seq.poses[0], dtype=np.float64)   # odometry alone, for the figures

    def motion(self, k: int) -> Motion:
        motion = planar_odometry(self.seq.poses, k, self.est, self.seed)
        self.dead_reckoning = compose(self.dead_reckoning, motion.increment)
        return motion

    def frame(self, k: int, in_map: np.ndarray | None) -> tuple[FrameData, np.ndarray]:
        """Frame ``k``'s detections (their noise already in them) and ``belief.clutter`` uniform
        false detections."""
        seq = self.seq
        rng = np.random.default_rng([self.seed, k, 101])
        R = seq.R[k].reshape(-1, 2, 2)
        cz, cR = self.clutter(rng, self.belief.clutter, nominal_noise(R, seq.nominal_R), seq.max_range, seq.fov)
        data = FrameData(np.vstack([seq.z[k].reshape(-1, 2), cz]), np.concatenate([R, cR]))
        return data, with_clutter_labels(seq.labels[k], self.belief.clutter, in_map)

    def state_columns(self, f, k: int) -> dict:
        seq = self.seq
        err = planar_pose_error(seq.poses[k], f.pose)
        return {**pose_columns("est_", f.R, f.p), **pose_columns("true_", seq.rotations[k], seq.positions[k]),
                "pos_err": float(np.linalg.norm(err[:2])), "rot_err_deg": float(np.rad2deg(abs(err[2]))),
                "nees": nees_or_nan(err, f.pose_covariance), "nees_dof": self.nees_dof,
                "odo_x": float(self.dead_reckoning[0]), "odo_y": float(self.dead_reckoning[1])}
