"""Planar landmark SLAM on a GTSAM factor graph, solved incrementally with iSAM2 (the GMU project's
back end). Poses ``X(k)`` (``Pose2``), landmarks ``L(map id)`` (``Point2``):

* start: a prior on ``X(0)`` (slam: the gauge, σ = 1e-6); localisation: a **joint** Gaussian prior
  over ``X(0)`` and the landmarks with P's full covariance (a common map error correlates them;
  per-landmark priors would be overconfident), a linear factor ``U δ`` (``UᵀU = Σ_t⁻¹``) in a
  ``LinearContainerFactor``;
* motion: ``BetweenFactorPose2(X(k−1), X(k), Δ)``, initial value ``x̂_{k−1} ⊕ Δ``;
* measurement: ``BearingRangeFactor2D(X(k), L(id), φ, r)``, R in GTSAM's (bearing, range) order.

``Pose2``'s tangent is body-frame, so covariances from GTSAM are mapped to world ``[δx, δy, δθ]`` by
``T = blockdiag(R(θ), 1, I₂…)`` (θ of the linearisation point), those given to it by ``Tᵀ``; an
increment's Q by ``blockdiag(R(Δθ)ᵀ, 1)``. Factors wait in a batch until the estimate is read. A
dropped tentative landmark's factors are removed: a smoother can undo a wrong association.

No landmark is born closer than ``MIN_INIT_RANGE``: a bearing swings by δp / r with a pose error, so
a landmark a few cm away never converges under iSAM2's one Gauss–Newton step per update, and its
chaos magnifies CPUs' last-bit rounding differences into different associations; ``check`` guards
iSAM2 with tolerances (configs/planar_isam2_ci.yaml).
"""

from __future__ import annotations

import numpy as np

from ..association.problem import Problem
from ..errors import UserError
from ..models.range_bearing import ANGULAR, inverse, jacobians, predict
from ..models.se2 import rot2, rz
from .base import CONFIRMED, Estimator, FrameData, LandmarkBook, Motion, UpdateReport
from .config import EstimatorConfig

GAUGE_SIGMA = 1e-6             # σ floor of the priors (m, rad): P = 0 in slam mode is the gauge
NOISE_FLOOR = 1e-5             # σ floor (m, rad) of every odometry and measurement noise given to GTSAM (_noise)
MIN_INIT_RANGE = 0.1           # m: no landmark is made from a feature closer than this (module docstring)
RELINEARIZE_THRESHOLD = 0.01   # iSAM2 relinearises a variable whose delta exceeds this (GTSAM's default 0.1)
RELINEARIZE_SKIP = 1           # ... checked at every update (GTSAM's default: every 10th)
RANGE_MARGIN = 0.05            # candidates up to (1 + this)·max_range ...
BEARING_MARGIN = np.deg2rad(2.0)   # ... and fov/2 + this: a post just past the edge is offered, not missed
JOINT_QUERIES = ("isam2", "elimination")   # how joint_covariance gets Σ_t (see there)


def import_gtsam():
    """The gtsam module, or a one-line ``UserError`` saying how to install it."""
    try:
        import gtsam
    except ImportError:
        raise UserError("estimator.name: isam2 needs the gtsam package: pip install 'assocbench[gtsam]' "
                        "(from a clone: pip install '.[gtsam]')") from None
    return gtsam


def tangent_to_world(theta: float, n_points: int) -> np.ndarray:
    """``T = blockdiag(R(θ), 1, I_{2n})``: world ``[δx, δy, δθ, δl…] = T [ξ, δl…]`` (module docstring)."""
    T = np.eye(3 + 2 * n_points)
    T[:2, :2] = rot2(theta)
    return T


class PlanarISAM2(Estimator):
    """iSAM2 smoother of a planar robot and point landmarks (see the module docstring)."""

    def __init__(self, cfg: EstimatorConfig, pose: np.ndarray, P: np.ndarray, landmarks: np.ndarray,
                 ids: np.ndarray, max_range: float, fov: float, joint: str = "isam2") -> None:
        """``joint``: how the problem's joint marginal is computed, ``isam2`` or ``elimination``
        (``joint_covariance``)."""
        self._g = gtsam = import_gtsam()
        if joint not in JOINT_QUERIES:
            raise UserError(f"joint must be one of {', '.join(JOINT_QUERIES)}, got {joint!r}")
        self.joint = joint
        pose, P, landmarks, ids = _checked_start(pose, P, landmarks, ids, max_range, fov)
        self.cfg, self.max_range, self.fov = cfg, float(max_range), float(fov)
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(RELINEARIZE_THRESHOLD)
        params.relinearizeSkip = RELINEARIZE_SKIP
        self.isam = gtsam.ISAM2(params)
        self.book = LandmarkBook()
        for map_id in ids:
            self.book.add(int(map_id), 0, confirmed=True)
        self.next_id = int(max(ids, default=-1)) + 1
        self.frame = 0
        self._factors_of: dict[int, list[int]] = {}   # map id -> indices of its factors in iSAM2's graph
        self._pending = (gtsam.NonlinearFactorGraph(), gtsam.Values(), [], [])   # factors, values, owners, removals
        self._last: tuple | None = None   # (candidate rows, frame data, strictly in view) of the last problem
        self._pose, self._L = np.array(pose), np.array(landmarks)
        self._add_priors(pose, P, landmarks, ids)
        self._flush()

    # ---------------------------------------------------------------- the interface

    def predict(self, motion: Motion) -> None:
        """``X(k+1)`` with initial value ``x̂_k ⊕ Δ`` and ``BetweenFactorPose2(X(k), X(k+1), Δ, Q_t)``."""
        g = self._g
        inc = np.asarray(motion.increment, dtype=float)
        Q = np.asarray(motion.covariance, dtype=float)
        if inc.shape != (3,) or Q.shape != (3, 3) or not (np.isfinite(inc).all() and np.isfinite(Q).all()):
            raise UserError(f"a planar Motion needs a finite increment (3,) and covariance (3, 3), "
                            f"got {inc.shape} and {Q.shape}")
        A = np.eye(3)
        A[:2, :2] = rot2(inc[2])
        delta = g.Pose2(*inc)
        start = g.Pose2(*self.pose)   # flushes the last frame's factors first
        graph, values, owners, _ = self._pending
        graph.add(g.BetweenFactorPose2(self._key_x(self.frame), self._key_x(self.frame + 1), delta,
                                       self._noise(A.T @ Q @ A)))
        owners.append(None)
        values.insert(self._key_x(self.frame + 1), start.compose(delta))
        self.frame += 1

    def problem(self, frame: FrameData) -> Problem:
        """Candidates within ``(1 + RANGE_MARGIN)·max_range`` and ``fov/2 + BEARING_MARGIN``;
        ``P = H Σ_w Hᵀ``, ``Σ_w = T Σ_t Tᵀ`` from the joint marginal of ``X(k)`` and the candidates
        (``joint_covariance``)."""
        z, R = _checked_frame(frame)
        pose, L = self.pose, self._L   # flushes
        zhat = predict(pose, L)
        near = zhat[:, 0] <= self.max_range * (1 + RANGE_MARGIN)
        ahead = np.abs(zhat[:, 1]) <= self.fov / 2 + BEARING_MARGIN
        rows = np.flatnonzero(near & ahead)
        strict = (zhat[rows, 0] <= self.max_range) & (np.abs(zhat[rows, 1]) <= self.fov / 2)
        P = np.zeros((0, 0))
        if len(rows):
            Sigma = self.joint_covariance(rows)
            H = _bundle_jacobian(*jacobians(pose, L[rows]))
            P = H @ Sigma @ H.T
            P = 0.5 * (P + P.T)
        self._last = (rows, FrameData(z, R, frame.depth), strict)
        ids = np.array([self.book.ids[r] for r in rows], np.int64)
        return Problem(z=z, R=R, zhat=zhat[rows], P=P, landmark_ids=ids,
                       volume=self.max_range * self.fov, angular=ANGULAR)

    def update(self, association: np.ndarray) -> UpdateReport:
        """A ``BearingRangeFactor2D`` per pairing; tentative landmarks confirmed and dropped as
        ``PlanarEKF`` does (a miss only strictly in view)."""
        rows, frame, strict = self._require_problem()
        a = np.asarray(association)
        if a.shape != (len(rows),) or (a.size and not np.issubdtype(a.dtype, np.integer)):
            raise UserError(f"association must be {len(rows)} integer feature indices (or -1), got shape {a.shape}")
        a = a.astype(np.int64)
        if np.any(a >= len(frame.z)) or np.any(a < -1):
            raise UserError(f"association names features outside -1..{len(frame.z) - 1}")
        paired = np.flatnonzero(a >= 0)
        for j in paired:
            self._add_measurement(self.book.ids[rows[j]], frame.z[a[j]], frame.R[a[j]])
        confirmed = self._count_observations(rows, a)
        removed = self._drop_tentative(rows, a, strict)
        return UpdateReport(len(paired), confirmed, removed)

    def initialise(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """Slam: ``L(id)`` at ``range_bearing.inverse(x̂_k, z_i)`` with its factor, per given
            feature within ``creation_room``; none closer than ``MIN_INIT_RANGE``."""
        if self.cfg.mode != "slam":
            return []
        z, R = _checked_frame(frame)
        features = np.asarray(features, dtype=np.int64).reshape(-1)
        if np.any((features < 0) | (features >= len(z))):
            raise UserError(f"initialise got feature indices outside 0..{len(z) - 1}")
        shortfall = self.cfg.target_paired - (len(z) - len(features))
        room = min(shortfall, self.cfg.max_new_per_frame, self.cfg.max_landmarks - len(self.book))
        made = []
        pose = self.pose
        for i in features[z[features, 0] >= MIN_INIT_RANGE][:max(room, 0)]:
            map_id = self.next_id
            self.next_id += 1
            self._pending[1].insert(self._key_l(map_id), self._g.Point2(*inverse(pose, z[i])))
            self._add_measurement(map_id, z[i], R[i])
            self.book.add(map_id, self.frame, confirmed=self.cfg.confirm_after <= 1)
            made.append((map_id, int(i)))
        return made

    @property
    def pose(self) -> np.ndarray:
        """Current pose estimate ``[x, y, θ]``."""
        self._flush()
        return self._pose.copy()

    @property
    def R(self) -> np.ndarray:
        """Rz(θ) (3, 3) of the current pose."""
        return rz(self.pose[2])

    @property
    def p(self) -> np.ndarray:
        """``(x, y, 0)`` of the current pose."""
        return np.r_[self.pose[:2], 0.0]

    @property
    def pose_covariance(self) -> np.ndarray:
        """Filtering marginal of ``X(k)`` (3, 3) in world ``[x, y, θ]``: ``T Σ_t Tᵀ``."""
        self._flush()
        T = tangent_to_world(self._theta_lin(), 0)
        return T @ self.isam.marginalCovariance(self._key_x(self.frame)) @ T.T

    @property
    def landmarks(self) -> np.ndarray:
        """Landmark estimates (N, 2) in book order."""
        self._flush()
        return self._L.copy()

    @property
    def covariance(self) -> np.ndarray:
        """Joint marginal (3 + 2N)² of the current pose and every landmark, world coordinates."""
        return self.joint_covariance(np.arange(len(self.book)))

    @property
    def trajectory(self) -> np.ndarray:
        """Smoothed estimate (k + 1, 3) of every pose so far: what the smoother believes now."""
        self._flush()
        est = self.isam.calculateEstimate()
        return np.array([_pose_array(est.atPose2(self._key_x(k))) for k in range(self.frame + 1)])

    def joint_covariance(self, rows: np.ndarray) -> np.ndarray:
        """``T Σ_t Tᵀ`` (3 + 2n)²: the joint marginal of ``X(k)`` and the landmarks ``rows`` at
        iSAM2's linearisation point, in world coordinates. ``joint = "isam2"`` asks
        ``ISAM2.jointMarginalCovariance`` (Bayes-tree shortcuts: usually fast, pathologically slow
        on some states); ``"elimination"`` eliminates the linearised graph with those keys last
        (``marginalMultifrontalBayesNet``), ``Σ_t = R⁻¹R⁻ᵀ``: O(graph) every call, never
        pathological (``benchmarks/isam2_rate.py``). Both agree to rounding."""
        self._flush()
        keys = [self._key_x(self.frame)] + [self._key_l(self.book.ids[r]) for r in rows]
        if self.joint == "isam2":
            Sigma = self.isam.jointMarginalCovariance(keys).fullMatrix()
        else:
            Sigma = self._joint_by_elimination(keys)
        T = tangent_to_world(self._theta_lin(), len(rows))
        return T @ Sigma @ T.T

    def _joint_by_elimination(self, keys: list[int]) -> np.ndarray:
        """Σ_t over ``keys`` from the linearised graph eliminated with ``keys`` last (``joint_covariance``)."""
        from scipy.linalg import solve_triangular
        linear = self.isam.getFactorsUnsafe().linearize(self.isam.getLinearizationPoint())
        R, _ = linear.marginalMultifrontalBayesNet(self._g.Ordering(keys)).matrix()
        R_inv = solve_triangular(R, np.eye(len(R)))
        return R_inv @ R_inv.T

    def _theta_lin(self) -> float:
        """Heading of ``X(k)``'s linearisation point, which Σ_t's tangent is at (it lags the
        estimate by up to ``RELINEARIZE_THRESHOLD``)."""
        return self.isam.getLinearizationPoint().atPose2(self._key_x(self.frame)).theta()

    # ---------------------------------------------------------------- helpers

    def _key_x(self, k: int) -> int:
        return self._g.symbol("x", k)

    def _key_l(self, map_id: int) -> int:
        return self._g.symbol("l", map_id)

    def _require_problem(self) -> tuple:
        if self._last is None:
            raise RuntimeError("update() needs the problem() of the same frame first")
        last, self._last = self._last, None
        return last

    def _add_priors(self, pose: np.ndarray, P: np.ndarray, landmarks: np.ndarray, ids: np.ndarray) -> None:
        """``X(0)``'s prior (slam), or the joint prior over ``X(0)`` and the landmarks (module docstring)."""
        g = self._g
        graph, values, owners, _ = self._pending
        values.insert(self._key_x(0), g.Pose2(*pose))
        for l, map_id in zip(landmarks, ids):
            values.insert(self._key_l(int(map_id)), g.Point2(*l))
        T = tangent_to_world(pose[2], len(ids))
        Sigma_t = T.T @ P @ T + GAUGE_SIGMA ** 2 * np.eye(len(P))
        if len(ids) == 0:
            graph.add(g.PriorFactorPose2(self._key_x(0), g.Pose2(*pose), g.noiseModel.Gaussian.Covariance(Sigma_t)))
        else:
            U = _upper_information_factor(Sigma_t)
            keys = [self._key_x(0)] + [self._key_l(int(m)) for m in ids]
            starts = [0] + [3 + 2 * j for j in range(len(ids))]
            terms = [(k, U[:, s:s + (3 if j == 0 else 2)]) for j, (k, s) in enumerate(zip(keys, starts))]
            prior = g.GaussianConditional(terms, len(keys), np.zeros(len(U)), g.noiseModel.Unit.Create(len(U)))
            graph.add(g.LinearContainerFactor(g.JacobianFactor(prior), values))
        owners.append(None)

    def _noise(self, S: np.ndarray):
        """GTSAM's Gaussian noise model of ``S`` with every eigenvalue raised to at least
        ``NOISE_FLOOR²`` (``S' = V max(Λ, σ_min² I) Vᵀ``): σ = 0 is a hard constraint iSAM2's
        Cholesky cannot eliminate, and a tiny σ swamps the Hessian ("Indeterminant linear system").
        ``S`` at or above the floor (every shipped setting) passes unchanged."""
        S = 0.5 * (S + S.T)
        w, V = np.linalg.eigh(S)
        if w[0] < NOISE_FLOOR ** 2:
            S = (V * np.maximum(w, NOISE_FLOOR ** 2)) @ V.T
        return self._g.noiseModel.Gaussian.Covariance(S)

    def _add_measurement(self, map_id: int, z: np.ndarray, R: np.ndarray) -> None:
        """``BearingRangeFactor2D(X(k), L(map_id), φ, r)`` with R permuted to (bearing, range)."""
        g = self._g
        swap = np.array([1, 0])
        graph, _, owners, _ = self._pending
        graph.add(g.BearingRangeFactor2D(self._key_x(self.frame), self._key_l(map_id), g.Rot2(float(z[1])), float(z[0]),
                                         self._noise(np.asarray(R)[np.ix_(swap, swap)])))
        owners.append(map_id)

    def _flush(self) -> None:
        """Send the pending factors, values and removals to iSAM2 (one update) and refresh the
        cached estimate of the current pose and the landmarks."""
        graph, values, owners, removals = self._pending
        if graph.size() == 0 and not removals:
            return
        result = self.isam.update(graph, values, removals)
        for owner, index in zip(owners, result.getNewFactorsIndices()):
            if owner is not None:
                self._factors_of.setdefault(owner, []).append(int(index))
        g = self._g
        self._pending = (g.NonlinearFactorGraph(), g.Values(), [], [])
        est = self.isam.calculateEstimate()
        self._pose = _pose_array(est.atPose2(self._key_x(self.frame)))
        self._L = np.array([est.atPoint2(self._key_l(m)) for m in self.book.ids], dtype=float).reshape(-1, 2)

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

    def _drop_tentative(self, rows: np.ndarray, a: np.ndarray, strict: np.ndarray) -> tuple[int, ...]:
        """Count misses of tentative candidates strictly in view and unassociated; remove those
        missed ``drop_after`` times, with their factors."""
        gone = []
        for r, f, inside in zip(rows, a, strict):
            if f < 0 and inside and self.book.status[r] != CONFIRMED:
                self.book.missed[r] += 1
                if self.book.missed[r] >= self.cfg.drop_after:
                    gone.append(int(r))
        if not gone:
            return ()
        removed = tuple(self.book.ids[r] for r in gone)
        for map_id in removed:
            self._pending[3].extend(self._factors_of.pop(map_id, []))
        keep = np.setdiff1d(np.arange(len(self.book)), gone)
        self.book.keep(keep)
        self._L = self._L[keep]
        return removed


def _pose_array(p) -> np.ndarray:
    return np.array([p.x(), p.y(), p.theta()])


def _upper_information_factor(Sigma: np.ndarray) -> np.ndarray:
    """Upper-triangular U with ``UᵀU = Σ⁻¹``: ``JΣJ = L Lᵀ`` (J the reversal) gives ``U = J L⁻¹ J``
    by one triangular solve."""
    from scipy.linalg import cholesky, solve_triangular
    n = len(Sigma)
    L = cholesky(Sigma[::-1, ::-1], lower=True)
    return solve_triangular(L, np.eye(n), lower=True)[::-1, ::-1]


def _bundle_jacobian(H_pose: np.ndarray, H_l: np.ndarray) -> np.ndarray:
    """H (2k, 3 + 2k) of k predictions over [pose, their landmarks] (block diagonal in the landmarks)."""
    k = len(H_l)
    H = np.zeros((2 * k, 3 + 2 * k))
    H[:, :3] = H_pose.reshape(2 * k, 3)
    j = np.arange(k)
    H[:, 3:].reshape(k, 2, k, 2)[j, :, j, :] = H_l
    return H


def _checked_start(pose, P, landmarks, ids, max_range, fov) -> tuple:
    """The constructor's arrays as floats, or a one-line ``UserError`` naming the bad one."""
    pose = np.asarray(pose, dtype=float)
    landmarks = np.asarray(landmarks, dtype=float)
    ids = np.asarray(ids).reshape(-1)
    if pose.shape != (3,):
        raise UserError(f"the planar pose must be (x, y, θ) of shape (3,), got {pose.shape}")
    if landmarks.ndim != 2 or landmarks.shape[1] != 2 or len(ids) != len(landmarks):
        raise UserError(f"landmarks must be (n, 2) with n ids, got {landmarks.shape} and {len(ids)} ids")
    n = len(ids)
    P = np.asarray(P, dtype=float)
    if P.shape != (3 + 2 * n,) * 2:
        raise UserError(f"P must be {(3 + 2 * n,) * 2} for {n} landmarks, got {P.shape}")
    if not all(np.isfinite(x).all() for x in (pose, landmarks, P)):
        raise UserError("the start pose, landmarks and P must be finite")
    if len(np.unique(ids)) != n or (n and not np.issubdtype(ids.dtype, np.integer)):
        raise UserError("landmark ids must be distinct integers")
    if not (np.isfinite(max_range) and max_range > 0) or not (0 < fov <= 2 * np.pi + 1e-12):
        raise UserError(f"max_range must be > 0 and fov in (0, 2π], got {max_range!r} and {fov!r}")
    return pose, P, landmarks, ids.astype(np.int64)


def _checked_frame(frame: FrameData) -> tuple[np.ndarray, np.ndarray]:
    z, R = np.asarray(frame.z, dtype=float), np.asarray(frame.R, dtype=float)
    if z.size == 0 and R.size == 0:   # no detections: any empty shape will do
        z, R = z.reshape(0, 2), R.reshape(0, 2, 2)
    if z.ndim != 2 or z.shape[1] != 2 or R.shape != (len(z), 2, 2):
        raise UserError(f"a planar frame needs z (m, 2) = (range, bearing) and R (m, 2, 2), "
                        f"got {z.shape} and {R.shape}")
    return z, R
