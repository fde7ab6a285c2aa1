"""Two-view landmark initialisation of the camera EKF-SLAM (``estimator.init: triangulation``).

A feature left unassociated in frame j waits as a ``View`` (its pixel ``u_a``, noise ``R_a``,
frame and index). In a later frame k each waiting view is paired with a still unassociated
feature ``u_b`` by ``triangulation.two_view_candidates`` (the nearest to its epipolar line,
within the gate, triangulating in front of both cameras), and the landmark is the DLT point
``l = X(u_a, u_b, ξ_j, ξ_k)`` of the two estimated poses.

The covariance: a clone of the pose. The landmark depends on the pose of frame j, whose error
is correlated with the current state (the current pose was predicted from it; the map was
built with it). So while views of frame j wait, the filter keeps a copy of ``ξ_j`` in its state
(stochastic cloning: appended at the end of frame j with ``ekf_core.augment`` and Jacobian I,
so ``P_cc = P_ξξ``, ``P_cx = P_ξ·``; predictions leave it alone, updates correct it through its
correlations, ``CameraEKF`` folds its correction into its nominal pose). The landmark is then
appended with the Jacobians w.r.t. both poses in the state and the pixels as the measurement:

    P_ll = J_s P_ss J_sᵀ + J_u M J_uᵀ,   P_lx = J_s P_s·,   s = [ξ_k, ξ_j],
    J_s = [∂X/∂[δp_b, δθ_b], ∂X/∂[δp_a, δθ_a]],   J_u = ∂X/∂(u_a, v_a, u_b, v_b),
    M = blockdiag(R_a, R_b),

all analytic and first order (``triangulation.pose_jacobian``, ``pixel_jacobian``), and the
clone is dropped (marginalised) once no view of frame j waits. This is the exact first-order
posterior. Why not the simpler choice (Jacobian w.r.t. the current pose only, ``Σ_j`` added to
M as if the old pose's error were independent of the state): in SLAM most of the two poses'
errors is shared drift, which moves both rays and the point together. Treated as independent,
it reads as a baseline error, magnified by depth / baseline along the ray, while across the ray
the point gets only about half of it (each ray carries it half-way), and the cross-covariance
with the current pose misses the rest. On a two-frame Monte Carlo (``tests/test_two_view_init``)
the true variance is 0.09 of that choice's along the ray and 1.9 times it across; in the loop
(oracle on the room, 30 / 60 / 100 frames, the constants below) it gives ANEES 12.4 / 12.1 /
30.2 (diverged at frame 50 of 100), the clone 6.2 / 7.5 / 7.3 (RGB-D depth: 7.3 / 9.1 / 7.7).
Cost: 6 state dimensions per frame with views waiting (at most ``MAX_WAIT + 1`` frames).

Gate and parallax (constants below; figures measured on the room with the oracle's filter
(RGB-D for the gate), σ = 1 px, f = 416 px, odometry σ_θ = 0.2°):

* a true pair's distance to the epipolar line moves with both pixels' noise and, for a
  rotation error δθ of the relative pose, by up to f δθ px; the relative pose of frames j and k
  is known at least to the odometry's ``(k − j) σ_θ²``. The gate is ``EPIPOLAR_SIGMAS`` times
  ``σ_epi = √(σ_a² + σ_b² + (k − j) f² σ_θ²)`` (σ² the larger eigenvalue of each R): 6.1 px
  there, which keeps 97.8 % of the true pairs of consecutive frames over 30 frames and 99.1 %
  over 100 (3 σ_pixel = 3 px keeps 91 % and 93 %: the poses' error is as large as the pixels');
* the DLT's first-order covariance holds while the relative depth spread is small
  (``triangulation.triangulation_covariance``: from the pixels, ``s ≈ √2 σ / (f · parallax)``; it
  misses a variance excess of about ``8 s²``, +9 % at s = 0.1, which is 1.9° of parallax at
  σ = 1 px, f ≈ 416 px). So a pair needs ``s ≤ MAX_PIXEL_SPREAD`` and the camera-relative depth
  σ / depth with the poses' errors included (``depth_spread``) ``≤ MAX_DEPTH_SPREAD``. The EKF
  asks more: a landmark kept as a 3-D point is updated through a projection that is far from
  linear in its depth while the depth is uncertain (Civera, Davison & Montiel 2008, the reason
  for inverse-depth landmarks), and its error then feeds back into the pose. With the oracle on
  the room (30 / 60 / 100 frames, so per-frame parallax ~3.3° / ~1.7° / ~1°), 2° of parallax
  gave ANEES 6.2 / 9.5 / 41 (diverged at frame 33 of 100), 4° 6.5 / 8.1 / 8.8, 6° 6.2 / 7.5 /
  7.3 with 9 / 16 / 15 confirmed landmarks (map RMSE 0.17 / 0.17 / 0.28 m), 8° 7.6 / 8.6 / 6.8
  with 4 / 9 / 4 (RGB-D depth: 7.3 / 9.1 / 7.7, 19 / 19 / 21, 0.05 / 0.09 / 0.10 m). Hence
  ``MIN_PARALLAX_DEG = 6``. With less, the view keeps waiting (the earlier view is kept, so the
  baseline grows; the new feature is used up), for at most ``MAX_WAIT`` frames. A view that
  finds no partner is dropped; one paired when the frame has no room left for landmarks is
  dropped too, and its partner waits in its place.

A pair along the epipolar line of a self-similar scene may be the wrong one (on the room,
rows of look-alike corners lie along the lines of a sideways motion); the landmark is made
tentative, and the filter's confirm/drop rule (``confirm_after``, ``drop_after``) with the
method's own association judges it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...models.camera import Intrinsics
from .triangulation import camera_matrix, pixel_jacobian, pose_jacobian, triangulate_dlt, two_view_candidates

EPIPOLAR_SIGMAS = 3.0      # gate on the distance to the epipolar line, in σ_epi (module docstring)
MIN_PARALLAX_DEG = 6.0     # the EKF's later updates need it, not just the DLT's covariance (module docstring)
MAX_PIXEL_SPREAD = 0.1     # s = √2 σ / (f · parallax) at most: the DLT's first-order limit, for larger σ
MAX_DEPTH_SPREAD = 0.1     # the same limit on the camera-relative depth σ / depth, pose errors included
MAX_WAIT = 10              # frames a view waits for parallax (each waiting frame is a 6-d clone in P)


@dataclass(frozen=True)
class View:
    """A feature waiting for a second view: pixel ``uv`` (2,), its noise ``R_px`` (2, 2), the
    ``frame`` it was seen in and its index ``feature`` there."""

    uv: np.ndarray
    R_px: np.ndarray
    frame: int
    feature: int


@dataclass(frozen=True)
class TwoViewLandmark:
    """A triangulated landmark ready for ``ekf_core.augment``: ``point`` (3,), its Jacobians
    ``J_current`` (3, 6) and ``J_first`` (3, 6) w.r.t. ``[δp, δθ]`` of the current pose and of the
    first view's pose, ``J_px`` (3, 4) w.r.t. ``(u_a, v_a, u_b, v_b)`` of noise ``M_px`` (4, 4);
    ``parallax_deg`` between the rays; ``first`` the first view."""

    point: np.ndarray
    J_current: np.ndarray
    J_first: np.ndarray
    J_px: np.ndarray
    M_px: np.ndarray
    parallax_deg: float
    first: View


def parallax_deg(point: np.ndarray, p_a: np.ndarray, p_b: np.ndarray) -> float:
    """Angle (deg) between the rays from the camera centres ``p_a`` and ``p_b`` to ``point``."""
    a, b = point - p_a, point - p_b
    cos = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-300)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def min_parallax_deg(sigma_px: float, f: float) -> float:
    """``max(MIN_PARALLAX_DEG, √2 σ / (MAX_PIXEL_SPREAD f))`` in degrees (module docstring)."""
    return max(MIN_PARALLAX_DEG, float(np.degrees(np.sqrt(2.0) * sigma_px / (MAX_PIXEL_SPREAD * f))))


def depth_spread(landmark: TwoViewLandmark, P_ss: np.ndarray, R: np.ndarray, p: np.ndarray) -> float:
    """σ of the landmark's depth ``z = e₃ᵀ Rᵀ (l − p)`` in the current camera ``(R, p)`` over z.
    With ``l`` = point + ``J_s e_s + J_u n`` (``e_s`` = [current pose, first pose] errors of
    covariance ``P_ss`` (12, 12), n the pixels') and ``δz = g (δl − δp) + e₃ᵀ [r_c]× δθ``,
    ``g = e₃ᵀ Rᵀ``: ``Var z = v P_ss vᵀ + g J_u M J_uᵀ gᵀ``, ``v = g J_s + [−g, e₃ᵀ [r_c]×, 0₆]``.
    It is the camera-relative spread: an error shared by the poses and the point moves nothing."""
    r_c = R.T @ (landmark.point - p)
    g = R[:, 2]   # e₃ᵀ Rᵀ
    v = g @ np.hstack([landmark.J_current, landmark.J_first])
    v[:3] -= g
    v[3:6] += np.cross([0.0, 0.0, 1.0], r_c)   # e₃ᵀ [r_c]× = (e₃ × r_c)ᵀ
    u = g @ landmark.J_px
    var = float(v @ P_ss @ v + u @ landmark.M_px @ u)
    return float(np.sqrt(max(var, 0.0))) / float(r_c[2])


def epipolar_gate(var_a: float, var_b: float, f: float, sigma_theta: float, frames: int) -> float:
    """``EPIPOLAR_SIGMAS √(σ_a² + σ_b² + frames f² σ_θ²)`` px: ``var_a``, ``var_b`` the pixel
    variances (px²) of the two features, ``σ_θ`` (rad) the odometry's rotation σ per frame and
    ``frames`` between the two views (module docstring)."""
    return EPIPOLAR_SIGMAS * float(np.sqrt(var_a + var_b + max(frames, 1) * (f * sigma_theta) ** 2))


def two_view_landmark(view: View, pose_a: tuple[np.ndarray, np.ndarray], uv: np.ndarray, R_px: np.ndarray,
                      R: np.ndarray, p: np.ndarray, K: Intrinsics) -> TwoViewLandmark:
    """The DLT point of ``view`` (seen from ``pose_a = (R_a, p_a)``) and pixel ``uv`` (noise
    ``R_px``) seen from the current pose ``(R, p)``, with its Jacobians (module docstring)."""
    P_a, P_b = camera_matrix(*pose_a, K), camera_matrix(R, p, K)
    point = triangulate_dlt(view.uv, uv, P_a, P_b)
    J_pose = pose_jacobian(view.uv, uv, P_a, P_b, K)   # [δξ_a (6), δξ_b (6)]
    M = np.zeros((4, 4))
    M[:2, :2], M[2:, 2:] = view.R_px, R_px
    return TwoViewLandmark(point, J_pose[:, 6:], J_pose[:, :6], pixel_jacobian(view.uv, uv, P_a, P_b), M,
                           parallax_deg(point, pose_a[1], p), view)


class TwoViewInitialiser:
    """The waiting views and their pairing (module docstring), one per filter; ``sigma_theta``
    is the odometry's rotation σ per frame (rad). The poses of the views' frames are the
    filter's (its clones), passed in at each step."""

    def __init__(self, K: Intrinsics, sigma_theta: float) -> None:
        self.K, self.sigma_theta = K, float(sigma_theta)
        self.waiting: list[View] = []

    @property
    def frames(self) -> set[int]:
        """The frames whose pose a waiting view needs."""
        return {v.frame for v in self.waiting}

    def step(self, frame: int, uv: np.ndarray, R_px: np.ndarray, features: np.ndarray, R: np.ndarray,
             p: np.ndarray, poses: dict[int, tuple[np.ndarray, np.ndarray]],
             pose_covariance: Callable[[int], np.ndarray], room: int) -> list[tuple[TwoViewLandmark, int]]:
        """Pair the waiting views (their frames' poses in ``poses``) with the unassociated
        ``features`` (indices into ``uv`` (m, 2) and ``R_px`` (m, 2, 2)) of ``frame``, seen from
        ``(R, p)``; return at most ``room`` landmarks with parallax enough and a spread small
        enough (``pose_covariance(j)``: the joint (12, 12) covariance of the current pose and
        frame j's), each with its feature's index. Afterwards the views still waiting and this
        frame's unpaired features wait."""
        free = [int(i) for i in features]
        var = np.linalg.eigvalsh(R_px)[:, -1] if len(R_px) else np.zeros(0)   # σ² of each feature
        made, still = [], []
        for view in self.waiting:
            if frame - view.frame > MAX_WAIT:
                continue
            j = self._partner(view, poses[view.frame], uv, var, free, frame, R, p)
            if j < 0:
                continue   # not seen again: dropped
            landmark = two_view_landmark(view, poses[view.frame], uv[j], R_px[j], R, p, self.K)
            sigma = np.sqrt(max(np.linalg.eigvalsh(view.R_px)[-1], var[j]))
            if (landmark.parallax_deg < min_parallax_deg(sigma, self.K.f)
                    or depth_spread(landmark, pose_covariance(view.frame), R, p) > MAX_DEPTH_SPREAD):
                free.remove(j)   # its second sighting, used up; the earlier view waits on
                still.append(view)
            elif len(made) < room:
                free.remove(j)
                made.append((landmark, j))
        self.waiting = still + [View(uv[i].copy(), R_px[i].copy(), frame, i) for i in free]
        return made

    def _partner(self, view: View, pose_a: tuple[np.ndarray, np.ndarray], uv: np.ndarray, var: np.ndarray,
                 free: list[int], frame: int, R: np.ndarray, p: np.ndarray) -> int:
        """Index (into ``uv``) of the free feature paired with ``view``, or -1; the gate takes the
        largest pixel variance among the free features."""
        if not free:
            return -1
        gate = epipolar_gate(np.linalg.eigvalsh(view.R_px)[-1], float(np.max(var[free])), self.K.f,
                             self.sigma_theta, frame - view.frame)
        j = two_view_candidates(view.uv, uv[free], *pose_a, R, p, self.K, gate)
        return free[j] if j >= 0 else -1
