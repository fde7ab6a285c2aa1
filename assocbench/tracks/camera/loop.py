"""What the camera track's closed loop reads from a sequence: pixels (plus RGB-D depth), 6-dof
odometry between frames, and the pose columns of a frame's record (6-dof pose error)."""

from __future__ import annotations

import numpy as np

from ...belief.config import BeliefConfig, with_clutter_labels
from ...estimators.base import FrameData, Motion
from ...estimators.config import EstimatorConfig
from ...scoring.trajectory import nees_or_nan, pose_columns, pose_error
from ...sim.odometry import odometry


class CameraSensor:
    """The camera track: pixels (+ RGB-D depth), 6-dof odometry and pose error."""

    nees_dof = 6
    new_landmark_gate = 0.0   # estimator.new_landmark_gate's default here: every unassociated feature

    def __init__(self, seq, belief: BeliefConfig, est: EstimatorConfig, seed: int) -> None:
        self.seq, self.belief, self.est, self.seed = seq, belief, est, seed

    def motion(self, k: int) -> Motion:
        return odometry(self.seq.rotations, self.seq.positions, k, self.est, self.seed)

    def frame(self, k: int, in_map: np.ndarray | None) -> tuple[FrameData, np.ndarray]:
        """Frame ``k``'s features plus N(0, σ_pixel²) when ``est.pixel_noise`` (after labelling, so
        no truth gate truncates it), then ``belief.clutter`` uniform features without depth; depth
        is the rendered one plus N(0, σ_z(z)²)."""
        seq, belief, est = self.seq, self.belief, self.est
        rng = np.random.default_rng([self.seed, k, 101])
        features = seq.features[k]
        clutter = rng.uniform([-0.5, -0.5], [seq.K.width - 0.5, seq.K.height - 0.5], (belief.clutter, 2))
        if est.pixel_noise:
            features = features + rng.normal(0.0, belief.sigma_pixel, features.shape)
        z = np.vstack([features, clutter])
        true_depth = np.concatenate([seq.depths[k] if seq.depths is not None else np.full(len(features), np.nan),
                                     np.full(belief.clutter, np.nan)])
        noisy = true_depth + rng.normal(0.0, 1.0, len(z)) * est.depth_std(np.nan_to_num(true_depth))
        R = np.repeat((belief.sigma_pixel ** 2 * np.eye(2))[None], len(z), axis=0)
        labels = with_clutter_labels(seq.labels[k], belief.clutter, in_map)
        return FrameData(z, R, noisy if seq.depths is not None else None), labels

    def state_columns(self, f, k: int) -> dict:
        seq = self.seq
        err = pose_error(seq.rotations[k], seq.positions[k], f.R, f.p)
        return {**pose_columns("est_", f.R, f.p), **pose_columns("true_", seq.rotations[k], seq.positions[k]),
                "pos_err": float(np.linalg.norm(err[:3])), "rot_err_deg": float(np.rad2deg(np.linalg.norm(err[3:]))),
                "nees": nees_or_nan(err, f.pose_covariance), "nees_dof": self.nees_dof}
