"""EKF localisation against a known map of wall lines (the line-features lecture, seed 003). The
state is the pose ``(x, y, θ)`` alone, covariance ``P`` (3, 3); the map lines are exact. Motion:
``planar_pose.motion_step``. Candidates: ``belief.candidate_lines``, ``ẑ_j = h(x̂, m_j)``,
``P = H P_pose Hᵀ``. Update with all pairs at once: ``ν = [wrap(α_i − α̂_j), r_i − r̂_j]`` stacked,
``R = blockdiag(R_i)``, ``S = H P Hᵀ + R`` (the lecture's Σ_IN), Joseph form
(``ekf_core.joseph_update``).
"""

from __future__ import annotations

import numpy as np

from ...association.problem import Problem
from ...errors import UserError
from ...estimators.base import Estimator, FrameData, LandmarkBook, Motion, UpdateReport
from ...estimators.config import EstimatorConfig
from ...estimators.ekf_core import block_diag, joseph_update, paired_innovations
from ...estimators.planar_pose import PlanarPoseViews, motion_step
from ...models.polar_line import ANGULAR, jacobians, predict
from ...models.range_bearing import wrap
from .belief import candidate_lines, pose_prediction_covariance

POSE = np.arange(3)
NOT_SLAM = ("the lines track localises on a known map of walls: estimator.mode slam is not available there, "
            "use estimator.mode: localisation")
NOT_ISAM2 = "estimator.name isam2 serves the planar (posts) track only; the lines track's estimator is ekf"


class LineEKF(PlanarPoseViews, Estimator):
    """EKF localisation on a known map of lines: ``lines`` (K, 2) ``(α_w, r_w)``; ``segments`` (S,
    2, 2) its faces' end points, ``segment_line`` (S,), ``segment_normal`` (S, 2); ``ids`` the
    mapped lines."""

    def __init__(self, cfg: EstimatorConfig, pose: np.ndarray, P: np.ndarray, lines: np.ndarray,
                 segments: np.ndarray, segment_line: np.ndarray, segment_normal: np.ndarray, ids: np.ndarray,
                 max_range: float, fov: float) -> None:
        if cfg.mode != "localisation":
            raise UserError(NOT_SLAM)
        self.cfg, self.max_range, self.fov = cfg, float(max_range), float(fov)
        (self._x, self.P, self._lines, self._segments, self._segment_line, self._normals,
         ids) = _checked(pose, P, lines, segments, segment_line, segment_normal, ids, max_range, fov)
        self._x[2] = wrap(self._x[2])
        self._ids = ids
        self.book = LandmarkBook()
        for map_id in ids:
            self.book.add(int(map_id), 0, confirmed=True)
        self.frame = 0
        self._last: tuple | None = None   # (rows, zhat, H_pose, frame) of the last problem

    # ---------------------------------------------------------------- the interface

    def predict(self, motion: Motion) -> None:
        """``x' = x ⊕ Δ``; ``P' = F P Fᵀ + G Q Gᵀ`` (``planar_pose.motion_step``)."""
        self._x, self.P = motion_step(self._x, self.P, motion)
        self.frame += 1

    def problem(self, frame: FrameData) -> Problem:
        """Candidates: the mapped lines ``candidate_lines`` gives for the estimate; ``zhat`` and the
        joint ``P = H P_pose Hᵀ`` (cross terms kept)."""
        _check_frame(frame)
        seen = candidate_lines(self._x, self._segments, self._segment_line, self._normals, len(self._lines),
                               self.max_range, self.fov)
        rows = np.flatnonzero(seen[self._ids])
        lines = self._lines[self._ids[rows]]
        zhat = predict(self._x, lines)
        H_pose, _ = jacobians(self._x, lines)
        self._last = (rows, zhat, H_pose, frame)
        return Problem(z=frame.z, R=frame.R, zhat=zhat, P=pose_prediction_covariance(H_pose, self.P),
                       landmark_ids=self._ids[rows], volume=self.max_range * self.fov, angular=ANGULAR)

    def update(self, association: np.ndarray) -> UpdateReport:
        """Joseph update with exactly the pairs of ``association`` (α innovations wrapped)."""
        if self._last is None:
            raise RuntimeError("update() needs the problem() of the same frame first")
        (rows, zhat, H_pose, frame), self._last = self._last, None
        a, paired, nu = paired_innovations(association, len(rows), frame.z, zhat, ANGULAR)
        if len(paired):
            dx, self.P = joseph_update(self.P, H_pose[paired].reshape(-1, 3), POSE, nu.ravel(),
                                       block_diag(frame.R[a[paired]]), overwrite=True)
            self._x = self._x + dx
            self._x[2] = wrap(self._x[2])
        self.book.observe(rows, a, self.cfg.confirm_after)
        return UpdateReport(len(paired))

    # ---------------------------------------------------------------- the state

    @property
    def landmarks(self) -> np.ndarray:
        """The map lines ``(α_w, r_w)`` (N, 2) in ``book`` order (exact: never updated)."""
        return self._lines[self._ids].copy()

    @property
    def covariance(self) -> np.ndarray:
        """The full covariance: the pose's (3, 3) (the map is exact)."""
        return self.P.copy()


def _checked(pose, P, lines, segments, segment_line, segment_normal, ids, max_range, fov) -> tuple:
    """The constructor's arrays as float64 / int64 copies, or a ``UserError`` naming the bad one."""
    pose = np.array(pose, dtype=float).reshape(-1)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise UserError(f"LineEKF pose must be a finite (x, y, θ) of shape (3,), got shape {pose.shape}")
    P = np.array(P, dtype=float)
    if P.shape != (3, 3) or not np.all(np.isfinite(P)):
        raise UserError(f"LineEKF P must be a finite (3, 3) pose covariance, got shape {P.shape}")
    L = np.array(lines, dtype=float).reshape(-1, 2) if np.size(lines) else np.zeros((0, 2))
    if not np.all(np.isfinite(L)) or np.any(L[:, 1] < 0):
        raise UserError("LineEKF lines must be finite (α_w, r_w) rows with r_w >= 0")
    seg = np.array(segments, dtype=float).reshape(-1, 2, 2) if np.size(segments) else np.zeros((0, 2, 2))
    seg_line = np.array(segment_line, dtype=np.int64).reshape(-1)
    normals = np.array(segment_normal, dtype=float).reshape(-1, 2) if np.size(segment_normal) else np.zeros((0, 2))
    if seg_line.shape != (len(seg),) or normals.shape != (len(seg), 2) or not np.all(np.isfinite(seg)):
        raise UserError(f"LineEKF needs one line index and one normal per segment: {len(seg)} segments, "
                        f"{seg_line.shape[0]} indices, {normals.shape[0]} normals")
    if np.any((seg_line < 0) | (seg_line >= len(L))):
        raise UserError(f"LineEKF segment_line must index the {len(L)} map lines")
    ids = np.array(ids, dtype=np.int64).reshape(-1)
    if len(np.unique(ids)) != len(ids) or np.any((ids < 0) | (ids >= len(L))):
        raise UserError(f"LineEKF ids must be distinct indices of the {len(L)} map lines")
    if not (np.isfinite(max_range) and max_range > 0):
        raise UserError(f"LineEKF max_range must be a positive number of metres, got {max_range!r}")
    if not (np.isfinite(fov) and 0 < fov <= 2 * np.pi + 1e-9):
        raise UserError(f"LineEKF fov must be in (0, 2π] radians, got {fov!r}")
    return pose, np.ascontiguousarray(P), L, seg, seg_line, normals, ids


def _check_frame(frame: FrameData) -> None:
    """A frame of lines: z (m, 2) rows (α, r), R (m, 2, 2)."""
    z, R = np.asarray(frame.z), np.asarray(frame.R)
    if z.ndim != 2 or z.shape[1] != 2 or R.shape != (len(z), 2, 2):
        raise UserError(f"a lines frame needs z (m, 2) rows (α, r) and R (m, 2, 2), got {z.shape} and {R.shape}")
