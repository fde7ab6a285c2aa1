"""Planar EKF-SLAM with range-bearing landmarks (the data association lecture's filter).

State ``x = [x, y, θ, l₁x, l₁y, …]`` with additive world-frame errors, θ wrapped after every step.
Motion: ``planar_pose.motion_step``; measurement ``z = (r, φ) = h(x, l)``
(``models.range_bearing``), bearing innovation wrapped, Joseph update (``ekf_core.joseph_update``);
new landmark ``l = g(x, z)`` with ``P_ll = G_x P_xx G_xᵀ + G_z R G_zᵀ`` (``ekf_core.augment``).

Candidates are the landmarks predicted within ``max_range`` and ``fov/2``, each bound widened by
``MARGIN_SIGMAS`` σ of the landmark's predicted range or bearing (just outside on the estimate may
be inside in truth); misses count only inside the nominal bounds, so the margin never drops a
landmark the sensor could not have seen.
"""

from __future__ import annotations

import numpy as np

from ..association.problem import Problem
from ..errors import UserError
from ..models.range_bearing import ANGULAR, inverse, inverse_jacobians, jacobians, predict, wrap
from .base import Estimator, FrameData, LandmarkBook, Motion, UpdateReport, creation_room
from .config import EstimatorConfig
from .ekf_core import (
    augment,
    block_diag,
    bundle_jacobian,
    joseph_update,
    paired_innovations,
    remove,
    state_columns,
)
from .planar_pose import PlanarPoseViews, motion_step

POSE = np.arange(3)
MARGIN_SIGMAS = 3.0   # candidate bounds widened by this many σ of the predicted range / bearing


class PlanarEKF(PlanarPoseViews, Estimator):
    """EKF-SLAM of a planar robot with range-bearing point landmarks (module docstring)."""

    def __init__(self, cfg: EstimatorConfig, pose: np.ndarray, P: np.ndarray, landmarks: np.ndarray,
                 ids: np.ndarray, max_range: float, fov: float) -> None:
        pose, P, L, ids = _checked(pose, P, landmarks, ids, max_range, fov)
        self.cfg, self.max_range, self.fov = cfg, float(max_range), float(fov)
        self._x = pose
        self._x[2] = wrap(pose[2])
        self._L = L
        self.P = P
        self.book = LandmarkBook()
        for map_id in ids:
            self.book.add(int(map_id), 0, confirmed=True)
        self.next_id = int(max(ids, default=-1)) + 1
        self.frame = 0
        self._last: tuple | None = None   # (rows, zhat, J_pose, J_l, inside, frame) of the last problem

    # ---------------------------------------------------------------- the interface

    def predict(self, motion: Motion) -> None:
        """``x' = x ⊕ Δ``; ``P' = F P Fᵀ + G Q Gᵀ`` on the pose block (``planar_pose.motion_step``)."""
        self._x, self.P = motion_step(self._x, self.P, motion)
        self.frame += 1

    def problem(self, frame: FrameData) -> Problem:
        """Candidates predicted in range and field of view (with the margin); ``zhat`` and
        ``P = H Σ Hᵀ`` over the pose and the candidates, cross terms kept."""
        _check_frame(frame)
        zhat = predict(self._x, self._L)
        J_pose, J_l = jacobians(self._x, self._L)
        sigma = np.sqrt(np.maximum(np.diagonal(self._marginal_blocks(J_pose, J_l), axis1=1, axis2=2), 0.0))
        in_range, in_fov = zhat[:, 0] <= self.max_range, self._in_fov(zhat[:, 1], 0.0)
        near = (zhat[:, 0] <= self.max_range + MARGIN_SIGMAS * sigma[:, 0]) & self._in_fov(
            zhat[:, 1], MARGIN_SIGMAS * sigma[:, 1])
        rows = np.flatnonzero(near)
        H = bundle_jacobian(J_pose[rows], J_l[rows])
        cols = state_columns(3, 2, rows)
        Pb = H @ self.P[np.ix_(cols, cols)] @ H.T
        self._last = (rows, zhat[rows], J_pose[rows], J_l[rows], (in_range & in_fov)[rows], frame)
        return Problem(z=frame.z, R=frame.R, zhat=zhat[rows], P=0.5 * (Pb + Pb.T),
                       landmark_ids=np.array([self.book.ids[r] for r in rows], dtype=np.int64),
                       volume=self.max_range * self.fov, angular=ANGULAR)

    def update(self, association: np.ndarray) -> UpdateReport:
        """Joseph update with exactly ``association``'s pairs (bearing wrapped); then confirm and
        drop tentative landmarks."""
        rows, zhat, J_pose, J_l, inside, frame = self._require_problem()
        a, paired, nu = paired_innovations(association, len(rows), frame.z, zhat, ANGULAR)
        if len(paired):
            dx, self.P = joseph_update(self.P, bundle_jacobian(J_pose[paired], J_l[paired]),
                                       state_columns(3, 2, rows[paired]), nu.ravel(),
                                       block_diag(frame.R[a[paired]]), overwrite=True)
            self._x = self._x + dx[:3]
            self._x[2] = wrap(self._x[2])
            self._L = self._L + dx[3:].reshape(-1, 2)
        confirmed = self.book.observe(rows, a, self.cfg.confirm_after)
        # only candidates predicted inside the nominal range and field of view can be missed
        removed = self._drop(self.book.miss(rows[inside], a[inside], self.cfg.drop_after))
        return UpdateReport(len(paired), confirmed, removed)

    def initialise(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """slam: a landmark ``g(x, z_i)`` per given feature in order, within ``creation_room``; a
            feature without a positive finite range is skipped. Localisation makes none."""
        if self.cfg.mode != "slam":
            return []
        _check_frame(frame)
        room = creation_room(self.cfg, len(frame.z), len(features), len(self.book))
        made = []
        for i in features:
            if len(made) >= room:
                break
            z = frame.z[int(i)]
            if not (np.all(np.isfinite(z)) and z[0] > 0):
                continue
            made.append((self._add(z, frame.R[int(i)]), int(i)))
        return made

    # ---------------------------------------------------------------- the state

    @property
    def landmarks(self) -> np.ndarray:
        return self._L.copy()

    @property
    def covariance(self) -> np.ndarray:
        return self.P.copy()

    # ---------------------------------------------------------------- helpers

    def _require_problem(self) -> tuple:
        if self._last is None:
            raise RuntimeError("update() needs the problem() of the same frame first")
        last, self._last = self._last, None
        return last

    def _in_fov(self, bearing: np.ndarray, margin: np.ndarray | float) -> np.ndarray:
        """Bearings within ``fov/2 + margin`` of the heading (all of them for a 360° sensor)."""
        if self.fov >= 2 * np.pi:
            return np.ones(len(bearing), dtype=bool)
        return np.abs(bearing) <= 0.5 * self.fov + margin

    def _marginal_blocks(self, J_pose: np.ndarray, J_l: np.ndarray) -> np.ndarray:
        """Each landmark's predicted covariance (N, 2, 2), ``H_j Σ_[pose, l_j] H_jᵀ``, from P's
        diagonal 5 × 5 blocks (O(N))."""
        n = len(self._L)
        i = 3 + 2 * np.arange(n)[:, None] + np.arange(2)                       # (N, 2) state indices
        P_pl = self.P[:3, 3:].reshape(3, n, 2).transpose(1, 0, 2)               # (N, 3, 2)
        P_ll = self.P[i[:, :, None], i[:, None, :]]                             # (N, 2, 2)
        cross = J_pose @ P_pl @ np.swapaxes(J_l, 1, 2)
        return J_pose @ self.P[:3, :3] @ np.swapaxes(J_pose, 1, 2) + cross + np.swapaxes(cross, 1, 2) \
            + J_l @ P_ll @ np.swapaxes(J_l, 1, 2)

    def _drop(self, gone: list[int]) -> tuple[int, ...]:
        """Remove the landmarks ``gone`` (state rows) from the state and the book; their map ids."""
        if not gone:
            return ()
        removed = tuple(self.book.ids[r] for r in gone)
        keep = np.setdiff1d(np.arange(len(self.book)), gone)
        self.P = remove(self.P, state_columns(3, 2, np.array(gone))[3:])
        self._L = self._L[keep]
        self.book.keep(keep)
        return removed

    def _add(self, z: np.ndarray, R_z: np.ndarray) -> int:
        """Append the landmark ``g(x, z)`` with its first-order covariance; tentative unless
        ``confirm_after`` is 1. Returns its map id."""
        G_pose, G_z = inverse_jacobians(self._x, z)
        self.P = augment(self.P, G_pose, POSE, G_z, R_z)
        self._L = np.vstack([self._L, inverse(self._x, z)])
        map_id = self.next_id
        self.next_id += 1
        self.book.add(map_id, self.frame, confirmed=self.cfg.confirm_after <= 1)
        return map_id


def _checked(pose, P, landmarks, ids, max_range, fov) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The constructor's arrays as float copies, or a ``UserError`` naming what is wrong."""
    pose = np.array(pose, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise UserError(f"PlanarEKF pose must be finite (x, y, θ) of shape (3,), got shape {pose.shape}")
    L = np.array(landmarks, dtype=float)
    if L.size == 0:
        L = L.reshape(0, 2)
    if L.ndim != 2 or L.shape[1] != 2 or not np.all(np.isfinite(L)):
        raise UserError(f"PlanarEKF landmarks must be finite (n, 2) positions, got shape {L.shape}")
    n = len(L)
    ids = np.array(ids, dtype=np.int64).reshape(-1)
    if ids.shape != (n,) or len(np.unique(ids)) != n:
        raise UserError(f"PlanarEKF ids must be {n} distinct map ids, one per landmark, got {ids.shape[0]}")
    P = np.array(P, dtype=float)
    if P.shape != (3 + 2 * n,) * 2 or not np.all(np.isfinite(P)):
        raise UserError(f"PlanarEKF P must be a finite {(3 + 2 * n,) * 2} covariance for {n} landmarks, got {P.shape}")
    if not (np.isfinite(max_range) and max_range > 0):
        raise UserError(f"PlanarEKF max_range must be a positive number of metres, got {max_range!r}")
    if not (np.isfinite(fov) and 0 < fov <= 2 * np.pi + 1e-9):
        raise UserError(f"PlanarEKF fov must be in (0, 2π] radians, got {fov!r}")
    return pose, np.ascontiguousarray(P), L, ids


def _check_frame(frame: FrameData) -> None:
    """A frame of range-bearing measurements: z (m, 2), R (m, 2, 2)."""
    z, R = np.asarray(frame.z), np.asarray(frame.R)
    if z.ndim != 2 or z.shape[1] != 2 or R.shape != (len(z), 2, 2):
        raise UserError(f"a planar frame needs z (m, 2) range-bearing rows and R (m, 2, 2), got {z.shape} and "
                        f"{R.shape}")
