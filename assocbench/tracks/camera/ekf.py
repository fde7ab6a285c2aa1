"""Camera EKF-SLAM: camera pose (position, orientation as an error state) and 3-D landmarks.

State ``x = [p, θ, l₁, …, l_N]`` with the nominal orientation ``R̂`` outside the vector,
``R = R̂ Exp(δθ)`` (``models.pinhole``'s perturbation), so the covariance is over
``[δp, δθ, δl₁, …]`` and never meets a rotation's singularity.

* Motion (body-frame ``Δp, Δθ``, covariance Q): ``p' = p + R̂ Δp``, ``R̂' = R̂ Exp(Δθ)``;
  ``F = [[I, −R̂[Δp]×], [0, Exp(Δθ)ᵀ]]``, ``G = blockdiag(R̂, I)``.
* Measurement: lab 8's pinhole bundle (``models.pinhole.predict_bundle``), Joseph update
  (``ekf_core.joseph_update``); the error is then folded into ``R̂ ← R̂ Exp(δθ)`` and θ's rows and
  columns mapped by the reset Jacobian ``G_r = I − ½[δθ]×``.
* RGB-D initialisation: ``l = p̂ + R̂ r_c``, ``r_c = z [(u−c_x)/f, (v−c_y)/f, 1]``: ``∂l/∂δp = I``,
  ``∂l/∂δθ = −R̂[r_c]×``,
  ``∂l/∂(u, v, z) = R̂ [[z/f, 0, (u−c_x)/f], [0, z/f, (v−c_y)/f], [0, 0, 1]]``.
* Two-view initialisation: ``two_view_init``; a waiting frame's pose clone sits after the landmarks
  in P (``covariance`` leaves clones out).
"""

from __future__ import annotations

import numpy as np

from ...association.problem import Problem
from ...estimators.base import Estimator, FrameData, LandmarkBook, Motion, UpdateReport, creation_room
from ...estimators.config import EstimatorConfig
from ...estimators.ekf_core import (
    augment,
    block_diag,
    bundle_jacobian,
    joseph_update,
    propagate_pose,
    remove,
    state_columns,
)
from ...models.camera import Intrinsics
from ...models.pinhole import exp_so3, predict_bundle, skew
from .two_view_init import TwoViewInitialiser

POSE = np.arange(6)


class CameraEKF(Estimator):
    """EKF-SLAM of a pinhole camera (see the module docstring for the equations)."""

    def __init__(self, K: Intrinsics, cfg: EstimatorConfig, R: np.ndarray, p: np.ndarray, P: np.ndarray,
                 landmarks: np.ndarray, normals: np.ndarray, ids: np.ndarray, max_view_angle: float = 75.0) -> None:
        n = len(landmarks)
        if P.shape != (6 + 3 * n, 6 + 3 * n):
            raise ValueError(f"P must be {(6 + 3 * n,) * 2} for {n} landmarks, got {P.shape}")
        self.K, self.cfg, self.max_view_angle = K, cfg, max_view_angle
        self.R, self.p = np.array(R, dtype=float), np.array(p, dtype=float)
        self._L = np.array(landmarks, dtype=float).reshape(n, 3)
        self._normals = np.array(normals, dtype=float).reshape(n, 3)
        self.P = np.array(P, dtype=float)
        self.book = LandmarkBook()
        for map_id in ids:
            self.book.add(int(map_id), 0, confirmed=True)
        self.next_id = int(max(ids, default=-1)) + 1
        self.frame = 0
        self._last: tuple | None = None   # (candidate rows, h, J_pose, J_l, frame data) of the last problem
        self._two_view = (TwoViewInitialiser(K, np.deg2rad(cfg.odometry_sigma_rotation))
                          if cfg.mode == "slam" and cfg.init == "triangulation" else None)
        self.first_sighting: dict[int, tuple[int, int]] = {}   # two-view map id -> (frame, feature) of its first view
        self._clones: list[int] = []   # frames whose pose is cloned after the landmarks in P (two_view_init)
        self._clone_poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}   # their nominal (R, p)

    # ---------------------------------------------------------------- the interface

    def predict(self, motion: Motion) -> None:
        """``p' = p + R̂ Δp``, ``R̂' = R̂ Exp(Δθ)``; ``P' = F P Fᵀ + G Q Gᵀ`` on the pose block."""
        dp, dtheta = motion.increment[:3], motion.increment[3:]
        dR = exp_so3(dtheta)
        F = np.eye(6)
        F[:3, 3:] = -self.R @ skew(dp[None])[0]
        F[3:, 3:] = dR.T
        G = np.zeros((6, 6))
        G[:3, :3], G[3:, 3:] = self.R, np.eye(3)
        self.P = propagate_pose(self.P, F, G @ motion.covariance @ G.T, overwrite=True)
        self.p = self.p + self.R @ dp
        self.R = self.R @ dR
        self.frame += 1

    def problem(self, frame: FrameData) -> Problem:
        """Candidates: landmarks in front, facing the camera within ``max_view_angle`` and predicted
        inside the image; ``P = H Σ Hᵀ`` over pose and candidate landmarks, cross terms kept."""
        h, J_pose, J_l, depth = predict_bundle(self.R, self.p, self._L, self.K)
        rows = np.flatnonzero(self._expected_in_view(h, depth))
        H = self._bundle_jacobian(J_pose[rows], J_l[rows])
        cols = self._columns(rows)
        Pb = H @ self.P[np.ix_(cols, cols)] @ H.T
        self._last = (rows, h[rows], J_pose[rows], J_l[rows], frame)
        return Problem(z=frame.z, R=frame.R, zhat=h[rows], P=0.5 * (Pb + Pb.T),
                       landmark_ids=np.array([self.book.ids[r] for r in rows], dtype=np.int64), volume=self.K.area)

    def update(self, association: np.ndarray) -> UpdateReport:
        """EKF update with the pairs of ``association``; confirms and drops tentative landmarks."""
        rows, h, J_pose, J_l, frame = self._require_problem()
        a = np.asarray(association, dtype=np.int64)
        paired = np.flatnonzero(a >= 0)
        if len(paired):
            H = self._bundle_jacobian(J_pose[paired], J_l[paired])
            cols = self._columns(rows[paired])
            nu = (frame.z[a[paired]] - h[paired]).ravel()
            R = block_diag(frame.R[a[paired]])
            dx, self.P = joseph_update(self.P, H, cols, nu, R, overwrite=True)
            self._inject(dx)
        confirmed = self._count_observations(rows, a)
        removed = self._drop_tentative(rows, a)
        return UpdateReport(len(paired), confirmed, removed)

    def initialise(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """RGB-D: a landmark from each feature with a positive finite depth, in order, within
        ``_room`` (the others are skipped; the caller counts them). ``init: triangulation``: the
        same caps, landmarks from two views (``two_view_init``)."""
        if self._two_view is not None:
            return self._initialise_two_view(frame, features)
        if self.cfg.mode != "slam" or frame.depth is None:
            return []
        room = self._room(frame, features)
        made = []
        for i in features:
            if len(made) >= room:
                break
            z = float(frame.depth[i])
            if not (np.isfinite(z) and z > 0):
                continue
            made.append((self._add_from_depth(frame.z[i], z, frame.R[i]), int(i)))
        return made

    @property
    def pose_covariance(self) -> np.ndarray:
        return self.P[:6, :6].copy()

    @property
    def landmarks(self) -> np.ndarray:
        return self._L.copy()

    @property
    def covariance(self) -> np.ndarray:
        m = 6 + 3 * len(self._L)   # without the two-view initialiser's pose clones
        return self.P[:m, :m].copy()

    @property
    def normals(self) -> np.ndarray:
        """Each landmark's outward normal: the map's in localisation, towards the camera that made
        it in slam."""
        return self._normals.copy()

    # ---------------------------------------------------------------- helpers

    def _require_problem(self) -> tuple:
        if self._last is None:
            raise RuntimeError("update() needs the problem() of the same frame first")
        last, self._last = self._last, None
        return last

    def _expected_in_view(self, h: np.ndarray, depth: np.ndarray) -> np.ndarray:
        to_cam = self.p - self._L
        cos_view = np.einsum("ij,ij->i", self._normals, to_cam) / np.maximum(np.linalg.norm(to_cam, axis=1), 1e-12)
        inside = self.K.in_image(np.nan_to_num(h, nan=-1e9, posinf=-1e9, neginf=-1e9))
        return (depth > 1e-3) & (cos_view > np.cos(np.deg2rad(self.max_view_angle))) & inside

    @staticmethod
    def _bundle_jacobian(J_pose: np.ndarray, J_l: np.ndarray) -> np.ndarray:
        """H (2k, 6 + 3k) of k predictions over [pose, their landmarks] (block diagonal in the landmarks)."""
        return bundle_jacobian(J_pose, J_l)

    @staticmethod
    def _columns(rows: np.ndarray) -> np.ndarray:
        """State columns of the pose and landmarks ``rows``."""
        return state_columns(6, 3, rows)

    def _inject(self, dx: np.ndarray) -> None:
        """Fold the error-state correction into the nominal state (pose clones included) and
        reset each δθ to zero."""
        self.p = self.p + dx[:3]
        self.R = self.R @ exp_so3(dx[3:6])
        n = 6 + 3 * len(self._L)
        self._L = self._L + dx[6:n].reshape(-1, 3)
        self._reset_theta(3, dx[3:6])
        for c, frame in enumerate(self._clones):
            o = n + 6 * c
            R_c, p_c = self._clone_poses[frame]
            self._clone_poses[frame] = (R_c @ exp_so3(dx[o + 3:o + 6]), p_c + dx[o:o + 3])
            self._reset_theta(o + 3, dx[o + 3:o + 6])

    def _reset_theta(self, o: int, dtheta: np.ndarray) -> None:
        """Map the θ rows and columns ``o:o+3`` of P by the reset Jacobian ``G_r = I − ½[δθ]×``."""
        G = np.eye(3) - 0.5 * skew(dtheta[None])[0]
        self.P[o:o + 3, :] = G @ self.P[o:o + 3, :]
        self.P[:, o:o + 3] = self.P[:, o:o + 3] @ G.T

    def _count_observations(self, rows: np.ndarray, a: np.ndarray) -> tuple[int, ...]:
        return self.book.observe(rows, a, self.cfg.confirm_after)

    def _drop_tentative(self, rows: np.ndarray, a: np.ndarray) -> tuple[int, ...]:
        """Count misses of tentative candidates left unassociated; remove those missed too often."""
        gone = self.book.miss(rows, a, self.cfg.drop_after)
        if not gone:
            return ()
        removed = tuple(self.book.ids[r] for r in gone)
        keep = np.setdiff1d(np.arange(len(self.book)), gone)
        self.P = remove(self.P, self._columns(np.array(gone))[6:])
        self._L, self._normals = self._L[keep], self._normals[keep]
        self.book.keep(keep)
        return removed

    def _room(self, frame: FrameData, features: np.ndarray) -> int:
        """How many landmarks this frame may make: the shortfall against ``target_paired``,
        ``max_new_per_frame``, ``max_landmarks``."""
        return creation_room(self.cfg, len(frame.z), len(features), len(self.book))

    def _initialise_two_view(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """Landmarks from waiting views paired with ``features``, appended with Jacobians to the
        current pose and the first view's clone (pixels as the measurement); then the clones follow
        the waiting views."""
        made = []
        for lm, i in self._two_view.step(self.frame, frame.z, frame.R, features, self.R, self.p, self._clone_poses,
                                         self._with_clone, max(self._room(frame, features), 0)):
            cols = np.concatenate([POSE, self._clone_columns(lm.first.frame)])
            map_id = self._append_landmark(lm.point, np.hstack([lm.J_current, lm.J_first]), lm.J_px, lm.M_px, cols)
            self.first_sighting[map_id] = (lm.first.frame, lm.first.feature)
            made.append((map_id, i))
        self._sync_clones()
        return made

    def _clone_columns(self, frame: int) -> np.ndarray:
        """State columns of the clone of ``frame``'s pose (after the landmarks, in ``_clones`` order)."""
        o = 6 + 3 * len(self._L) + 6 * self._clones.index(frame)
        return np.arange(o, o + 6)

    def _with_clone(self, frame: int) -> np.ndarray:
        """Joint covariance (12, 12) of the current pose and the clone of ``frame``'s."""
        cols = np.concatenate([POSE, self._clone_columns(frame)])
        return self.P[np.ix_(cols, cols)]

    def _sync_clones(self) -> None:
        """Marginalise clones no waiting view needs; clone the current pose (``augment``, Jacobian
        I, no measurement) if this frame's views wait."""
        needed = self._two_view.frames
        gone = [c for c in self._clones if c not in needed]
        if gone:
            self.P = remove(self.P, np.concatenate([self._clone_columns(c) for c in gone]))
            self._clones = [c for c in self._clones if c in needed]
            for c in gone:
                del self._clone_poses[c]
        if self.frame in needed and self.frame not in self._clones:
            self.P = augment(self.P, np.eye(6), POSE, np.zeros((6, 1)), np.zeros((1, 1)))
            self._clones.append(self.frame)
            self._clone_poses[self.frame] = (self.R.copy(), self.p.copy())

    def _add_from_depth(self, uv: np.ndarray, z: float, R_uv: np.ndarray) -> int:
        """Append the landmark back-projected from pixel ``uv`` at depth ``z`` (module docstring)."""
        f, cx, cy = self.K.f, self.K.cx, self.K.cy
        rc = np.array([(uv[0] - cx) / f * z, (uv[1] - cy) / f * z, z])
        landmark = self.p + self.R @ rc
        J_state = np.hstack([np.eye(3), -self.R @ skew(rc[None])[0]])
        J_meas = self.R @ np.array([[z / f, 0.0, (uv[0] - cx) / f], [0.0, z / f, (uv[1] - cy) / f], [0.0, 0.0, 1.0]])
        M = np.zeros((3, 3))
        M[:2, :2] = R_uv
        M[2, 2] = float(self.cfg.depth_std(z)) ** 2
        return self._append_landmark(landmark, J_state, J_meas, M)

    def _append_landmark(self, landmark: np.ndarray, J_state: np.ndarray, J_meas: np.ndarray, M: np.ndarray,
                         state_cols: np.ndarray = POSE) -> int:
        """Append ``landmark`` with ``ekf_core.augment`` (``J_state`` on ``state_cols``, ``J_meas``
        of a measurement of covariance ``M``) before any pose clones; tentative unless
        ``confirm_after`` is 1."""
        self.P = augment(self.P, J_state, state_cols, J_meas, M)
        if self._clones:   # the clones stay last: move the new rows in front of them
            n, N = 6 + 3 * len(self._L), len(self.P)
            order = np.r_[0:n, N - 3:N, n:N - 3]
            self.P = self.P[np.ix_(order, order)]
        self._L = np.vstack([self._L, landmark])
        to_cam = self.p - landmark
        self._normals = np.vstack([self._normals, to_cam / np.linalg.norm(to_cam)])
        map_id = self.next_id
        self.next_id += 1
        self.book.add(map_id, self.frame, confirmed=self.cfg.confirm_after <= 1)
        return map_id

