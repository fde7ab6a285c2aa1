"""A recorded log as the track's sequence: a frame per pose with a sighting, the odometry between
them, the sightings in range-bearing, and the reference solution's path and map. Poses without a
sighting pose no association problem, so the closed loop predicts through them at once with their
increments composed (exactly; the covariance to first order, as a pose-by-pose EKF would). Frame k's
scored pose is the reference solution's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...estimators.base import Motion
from ...estimators.planar_pose import motion_step
from ...sim.robot_path import PosesInPlane
from ...sources.range_bearing_log import RangeBearingLog
from .reference import ReferenceSolution
from .settings import LogConfig

# rad added to twice the widest bearing of a log (the default field of view): a landmark sighted at the
# widest bearing lies just outside a view of exactly that width from a slightly wrong heading
FOV_MARGIN = np.deg2rad(10.0)


@dataclass
class LogSequence(PosesInPlane):
    """Frames of a log. pose_index: (F,) each frame's log pose. poses: (F, 3) the reference's.
    increments: (F, 3) from frame k−1 to k in k−1's frame (row 0 zeros). motion_covariances: (F, 3,
    3), times ``log.odometry_scale``. z, R, labels: per frame, labels the reference landmark (−1:
    none). visible: (F, L). landmarks: (L, 2) the reference map; landmark_ids: (L,) their log ids."""

    name: str
    pose_index: np.ndarray
    poses: np.ndarray
    increments: np.ndarray
    motion_covariances: np.ndarray
    z: list[np.ndarray]
    R: list[np.ndarray]
    labels: list[np.ndarray]
    visible: np.ndarray
    landmarks: np.ndarray
    landmark_ids: np.ndarray
    max_range: float
    fov: float
    nominal_R: np.ndarray
    reference: str            # how the reference solution was made and how well it fits (one line)
    track = "planar_log"


def frame_poses(log: RangeBearingLog, frames: int | None = None) -> np.ndarray:
    """The log poses that are frames: those with a sighting, the first ``frames`` of them."""
    return np.unique(log.sighting_pose)[:frames]


def sensor_bounds(log: RangeBearingLog, cfg: LogConfig) -> tuple[float, float]:
    """``(max_range m, fov rad)``: the settings', else the farthest sighting and twice the widest
    bearing plus ``FOV_MARGIN`` (at most 2π)."""
    z, _ = log.range_bearing()
    max_range = cfg.max_range if cfg.max_range is not None else float(z[:, 0].max(initial=0.0))
    widest = 2 * float(np.abs(z[:, 1]).max(initial=0.0)) + FOV_MARGIN
    fov = np.deg2rad(cfg.fov_deg) if cfg.fov_deg is not None else min(2 * np.pi, widest)
    return max_range, fov


def composed_motion(increments: np.ndarray, covariances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Δ = Δ₁ ⊕ Δ₂ ⊕ …`` and its covariance propagated as the EKF predicts
    (``planar_pose.motion_step``)."""
    pose, P = np.zeros(3), np.zeros((3, 3))
    for inc, Q in zip(increments, covariances):
        pose, P = motion_step(pose, P, Motion(inc, Q))
    return pose, P


def make_log_sequence(log: RangeBearingLog, reference: ReferenceSolution, cfg: LogConfig,
                      frames: int | None = None) -> LogSequence:
    """The sequence of ``log``'s first ``frames`` frames (all: None) under the settings ``cfg``."""
    at = frame_poses(log, frames)
    increments, covariances = np.zeros((len(at), 3)), np.zeros((len(at), 3, 3))
    for k in range(1, len(at)):
        steps = slice(at[k - 1], at[k])
        increments[k], covariances[k] = composed_motion(log.increments[steps], log.increment_covariances[steps])
    z, R = log.range_bearing()
    labels = reference.index_of(log.sighting_ref)
    rows = np.split(np.arange(len(z)), np.searchsorted(log.sighting_pose, at[1:]))
    rows = [r[log.sighting_pose[r] == pose] for r, pose in zip(rows, at)]
    visible = np.zeros((len(at), len(reference.ids)), bool)
    for k, r in enumerate(rows):
        visible[k, labels[r][labels[r] >= 0]] = True
    max_range, fov = sensor_bounds(log, cfg)
    return LogSequence(
        name=log.name, pose_index=at, poses=reference.poses[at], increments=increments,
        motion_covariances=cfg.odometry_scale * covariances, z=[z[r] for r in rows], R=[R[r] for r in rows],
        labels=[labels[r] for r in rows], visible=visible, landmarks=reference.landmarks, landmark_ids=reference.ids,
        max_range=max_range, fov=fov, nominal_R=np.median(R, axis=0) if len(R) else np.eye(2),
        reference=reference.describe())
