"""Camera EKF-SLAM: camera pose (position, orientation as an error state) and 3-D landmarks.

State ``x = [p, θ, l₁, …, l_N]`` with the nominal orientation ``R̂`` kept outside the vector:
``R = R̂ Exp(δθ)`` (body-frame error, the perturbation ``belief.pinhole`` takes its Jacobians
with), so the covariance is over ``[δp, δθ, δl₁, …]`` and never meets a rotation's singularity.

* Motion (body-frame increment ``Δp, Δθ`` with covariance Q):
  ``p' = p + R̂ Δp``, ``R̂' = R̂ Exp(Δθ)``; ``F = [[I, −R̂[Δp]×], [0, Exp(Δθ)ᵀ]]``,
  ``G = blockdiag(R̂, I)``.
* Measurement: lab 8's pinhole bundle ``h(x)`` and Jacobians (``belief.pinhole.predict_bundle``),
  updated in Joseph form (``ekf_core.joseph_update``). After an update the error is folded into
  the nominal state, ``R̂ ← R̂ Exp(δθ)``, and the covariance's θ rows and columns are mapped by
  the reset Jacobian ``G_r = I − ½[δθ]×``.
* RGB-D initialisation: ``l = p̂ + R̂ r_c`` with ``r_c = z [(u−c_x)/f, (v−c_y)/f, 1]``:
  ``∂l/∂δp = I``, ``∂l/∂δθ = −R̂[r_c]×``, ``∂l/∂(u, v, z) = R̂ [[z/f, 0, (u−c_x)/f], [0, z/f, (v−c_y)/f], [0, 0, 1]]``.
"""

from __future__ import annotations

import math

import numpy as np

from ..association.problem import Problem
from ..belief.pinhole import predict_bundle, skew
from ..sim.camera import Intrinsics
from .base import CONFIRMED, Estimator, FrameData, LandmarkBook, Motion, UpdateReport
from .config import EstimatorConfig
from .ekf_core import augment, joseph_update, propagate_pose, remove

POSE = np.arange(6)


def exp_so3(v: np.ndarray) -> np.ndarray:
    """Rotation matrix ``Exp(v)`` of a rotation vector, by Rodrigues' formula
    ``I + a [v]× + b [v]×²`` with ``a = sin θ / θ``, ``b = (1 − cos θ) / θ²``, θ = ‖v‖ and
    ``[v]×² = v vᵀ − θ² I``; below θ = 1e-4, where a and b cancel, their Taylor series (the next
    terms are below 1e-17 there). Equal to scipy's ``Rotation.from_rotvec(v).as_matrix()`` to
    rounding (7e-16 measured), at a quarter of its cost: it runs on every predict and update."""
    x, y, z = (float(c) for c in v)
    t2 = x * x + y * y + z * z
    if t2 < 1e-8:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    return np.array([[1.0 - b * (y * y + z * z), b * x * y - a * z, b * x * z + a * y],
                     [b * x * y + a * z, 1.0 - b * (x * x + z * z), b * y * z - a * x],
                     [b * x * z - a * y, b * y * z + a * x, 1.0 - b * (x * x + y * y)]])


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
            R = _block_diag(frame.R[a[paired]])
            dx, self.P = joseph_update(self.P, H, cols, nu, R, overwrite=True)
            self._inject(dx)
        confirmed = self._count_observations(rows, a)
        removed = self._drop_tentative(rows, a)
        return UpdateReport(len(paired), confirmed, removed)

    def initialise(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """RGB-D: a landmark from each feature with a valid depth, in the given order, while the
        frame paired fewer than ``target_paired`` features (at most the shortfall), at most
        ``max_new_per_frame`` per frame and ``max_landmarks`` in the map. Features without a
        positive finite depth are skipped (the caller counts them)."""
        if self.cfg.mode != "slam" or frame.depth is None:
            return []
        shortfall = self.cfg.target_paired - (len(frame.z) - len(features))
        room = min(shortfall, self.cfg.max_new_per_frame, self.cfg.max_landmarks - len(self.book))
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
        return self.P.copy()

    @property
    def normals(self) -> np.ndarray:
        """Each landmark's outward normal: the map's in localisation, the direction towards the
        camera that made it in slam (the estimate knows no surface)."""
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
        k = len(J_l)
        H = np.zeros((2 * k, 6 + 3 * k))
        H[:, :6] = J_pose.reshape(2 * k, 6)
        j = np.arange(k)
        H[:, 6:].reshape(k, 2, k, 3)[j, :, j, :] = J_l   # the (2, 3) blocks on the diagonal
        return H

    @staticmethod
    def _columns(rows: np.ndarray) -> np.ndarray:
        """State columns of the pose and landmarks ``rows``."""
        lm = (6 + 3 * np.asarray(rows)[:, None] + np.arange(3)).ravel()
        return np.concatenate([POSE, lm]).astype(np.int64)

    def _inject(self, dx: np.ndarray) -> None:
        """Fold the error-state correction into the nominal state and reset δθ to zero."""
        self.p = self.p + dx[:3]
        self.R = self.R @ exp_so3(dx[3:6])
        self._L = self._L + dx[6:].reshape(-1, 3)
        G = np.eye(3) - 0.5 * skew(dx[3:6][None])[0]
        self.P[3:6, :] = G @ self.P[3:6, :]
        self.P[:, 3:6] = self.P[:, 3:6] @ G.T

    def _count_observations(self, rows: np.ndarray, a: np.ndarray) -> tuple[int, ...]:
        confirmed = []
        for r, f in zip(rows, a):
            if f < 0:
                continue
            self.book.observed[r] += 1
            if self.book.status[r] != CONFIRMED and self.book.observed[r] >= self.cfg.confirm_after:
                self.book.status[r] = CONFIRMED
                confirmed.append(self.book.ids[r])
        return tuple(confirmed)

    def _drop_tentative(self, rows: np.ndarray, a: np.ndarray) -> tuple[int, ...]:
        """Count misses of tentative candidates left unassociated; remove those missed too often."""
        gone = []
        for r, f in zip(rows, a):
            if f < 0 and self.book.status[r] != CONFIRMED:
                self.book.missed[r] += 1
                if self.book.missed[r] >= self.cfg.drop_after:
                    gone.append(int(r))
        if not gone:
            return ()
        removed = tuple(self.book.ids[r] for r in gone)
        keep = np.setdiff1d(np.arange(len(self.book)), gone)
        self.P = remove(self.P, self._columns(np.array(gone))[6:])
        self._L, self._normals = self._L[keep], self._normals[keep]
        self.book.keep(keep)
        return removed

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
        self.P = augment(self.P, J_state, POSE, J_meas, M)
        self._L = np.vstack([self._L, landmark])
        to_cam = self.p - landmark
        self._normals = np.vstack([self._normals, to_cam / np.linalg.norm(to_cam)])
        map_id = self.next_id
        self.next_id += 1
        self.book.add(map_id, self.frame, confirmed=self.cfg.confirm_after <= 1)
        return map_id


def _block_diag(blocks: np.ndarray) -> np.ndarray:
    """Block-diagonal matrix of k (d, d) blocks."""
    k, d, _ = blocks.shape
    out = np.zeros((k * d, k * d))
    j = np.arange(k)
    out.reshape(k, d, k, d)[j, :, j, :] = blocks
    return out
