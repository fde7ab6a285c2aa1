"""What the closed loop reads from a sequence, per track: a frame's measurements and their truth
labels, the odometry between frames, and the pose columns of a frame's record.

The camera track measures pixels (plus RGB-D depth) and moves in 3-D (6-dof pose error); the
planar track measures post ranges and bearings and moves in the plane (3-dof pose error
``[δx, δy, δθ]``); the lines track is the planar one with wall lines ``(α, r)`` for posts.
``ClosedLoop`` calls these through ``loop_sensor(seq, ...)`` and never asks
which track it runs.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..association.problem import NO_MATCH
from ..belief.config import BeliefConfig, with_clutter_labels
from ..tracks.lines.belief import clutter_lines
from ..belief.planar import clutter_detections, nominal_noise
from ..models.range_bearing import pose_error as planar_pose_error
from ..models.se2 import compose
from ..estimators.base import FrameData, Motion
from ..estimators.config import EstimatorConfig
from ..scoring.trajectory import pose_error, pose_nees
from ..sim.odometry import odometry, planar_odometry
from ..tracks.lines.plots import segment_status, snapshot_json


def pose_columns(prefix: str, R: np.ndarray, p: np.ndarray) -> dict[str, float]:
    """``{prefix}x … {prefix}qw``: a pose as TUM's position and scalar-last quaternion."""
    q = Rotation.from_matrix(R).as_quat()
    return {f"{prefix}{k}": float(v) for k, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), (*p, *q))}


def _nees(error: np.ndarray, cov: np.ndarray) -> float:
    """Pose NEES, NaN while the pose covariance is zero (slam's first frame fixes the gauge)."""
    return pose_nees(error, cov) if np.any(cov) else float("nan")


class CameraSensor:
    """The camera track: pixels (+ RGB-D depth), 6-dof odometry and pose error."""

    nees_dof = 6
    new_landmark_gate = 0.0   # estimator.new_landmark_gate's default here: every unassociated feature

    def __init__(self, seq, belief: BeliefConfig, est: EstimatorConfig, seed: int) -> None:
        self.seq, self.belief, self.est, self.seed = seq, belief, est, seed

    def motion(self, k: int) -> Motion:
        return odometry(self.seq.rotations, self.seq.positions, k, self.est, self.seed)

    def frame(self, k: int, in_map: np.ndarray | None) -> tuple[FrameData, np.ndarray]:
        """Frame ``k``'s features plus N(0, σ_pixel²) when ``est.pixel_noise`` (drawn after labelling:
        a truth gate must not truncate the noise), then ``belief.clutter`` uniform clutter features
        with no depth; the measured depth is the rendered one plus N(0, σ_z(z)²)."""
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
                "nees": _nees(err, f.pose_covariance), "nees_dof": self.nees_dof}


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
        """Frame ``k``'s detections (their noise is the sensor's, already in them) and
        ``belief.clutter`` false detections (``clutter``: uniform over the measurement space)."""
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
                "nees": _nees(err, f.pose_covariance), "nees_dof": self.nees_dof,
                "odo_x": float(self.dead_reckoning[0]), "odo_y": float(self.dead_reckoning[1])}


class LinesSensor(PlanarSensor):
    """The lines track: extracted wall lines ``(α, r)`` (their covariance is the extractor's) plus
    clutter lines uniform over α × r, planar odometry, 3-dof pose error: the planar sensor with
    lines for posts. Localisation only (the map is known), so no new-landmark gate applies."""

    new_landmark_gate = 0.0   # unused: the lines track makes no landmarks
    clutter = staticmethod(clutter_lines)

    def snapshot(self, k: int, pose: np.ndarray, problem, association: np.ndarray, labels: np.ndarray) -> str:
        """The last frame for the top view (``viz.line_plots``): the scan's points, the extracted
        segments and what the method did with each, to be drawn at the estimated ``pose``."""
        m = len(self.seq.z[k])   # the extracted lines; the clutter lines after them have no segment
        status = segment_status(labels, problem.landmark_ids, association, m)
        return snapshot_json(pose, self.seq.final_points, self.seq.endpoints[k], status)


SENSORS = {"planar": PlanarSensor, "lines": LinesSensor}


def loop_sensor(seq, belief: BeliefConfig, est: EstimatorConfig, seed: int) -> CameraSensor | PlanarSensor:
    """The sensor side of ``seq``'s track."""
    return SENSORS.get(getattr(seq, "track", "camera"), CameraSensor)(seq, belief, est, seed)
