"""Two-view landmark initialisation of the camera EKF-SLAM (``estimator.init: triangulation``). A
feature left unassociated in frame j waits as a ``View``; in a later frame k it is paired with an
unassociated feature ``u_b`` (``triangulation.two_view_candidates``: nearest the epipolar line
within the gate, in front of both cameras), and the landmark is the DLT point
``l = X(u_a, u_b, ξ_j, ξ_k)``.

**A clone of the pose.** ``l`` depends on ξ_j, correlated with the state, so while views of frame j
wait the filter keeps a copy of ξ_j (stochastic cloning: ``ekf_core.augment`` with Jacobian I) and
the landmark is appended with Jacobians to both poses, the pixels as the measurement:

    P_ll = J_s P_ss J_sᵀ + J_u M J_uᵀ,   P_lx = J_s P_s·,   s = [ξ_k, ξ_j],
    J_s = [∂X/∂[δp_b, δθ_b], ∂X/∂[δp_a, δθ_a]],   J_u = ∂X/∂(u_a, v_a, u_b, v_b),
    M = blockdiag(R_a, R_b),

the exact first-order posterior (treating ξ_j's error as independent would misread shared drift as a
baseline error: tests/test_two_view_init). The clone is marginalised once no view of frame j waits.

**Gate and parallax.** The gate is ``EPIPOLAR_SIGMAS · √(σ_a² + σ_b² + (k − j) f² σ_θ²)`` (both
pixels' noise and the relative rotation's, at least the odometry's). A pair needs the DLT's relative
depth spread ``s ≈ √2 σ / (f · parallax)`` ≤ ``MAX_PIXEL_SPREAD`` and
``depth_spread ≤ MAX_DEPTH_SPREAD``, and ``MIN_PARALLAX_DEG``: a 3-D point updated through a
projection far from linear in its depth feeds its error back into the pose (Civera, Davison &
Montiel 2008). With less, the view waits (at most ``MAX_WAIT`` frames); a view without partner is
dropped. A pair on a self-similar scene may be wrong, so the landmark is tentative.
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
    """A triangulated landmark for ``ekf_core.augment``: ``point`` (3,), Jacobians ``J_current`` and
    ``J_first`` (3, 6) to ``[δp, δθ]`` of the current and first view's poses, ``J_px`` (3, 4) to the
    pixels of noise ``M_px`` (4, 4); ``parallax_deg``; ``first`` the first view."""

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
    """σ of the landmark's depth ``z = e₃ᵀ Rᵀ (l − p)`` in the current camera over z: with ``l`` =
    point + ``J_s e_s + J_u n`` and ``δz = g (δl − δp) + e₃ᵀ [r_c]× δθ``, ``g = e₃ᵀ Rᵀ``,
    ``Var z = v P_ss vᵀ + g J_u M J_uᵀ gᵀ``, ``v = g J_s + [−g, e₃ᵀ [r_c]×, 0₆]``. Camera-relative:
    an error shared by the poses and the point moves nothing."""
    r_c = R.T @ (landmark.point - p)
    g = R[:, 2]   # e₃ᵀ Rᵀ
    v = g @ np.hstack([landmark.J_current, landmark.J_first])
    v[:3] -= g
    v[3:6] += np.cross([0.0, 0.0, 1.0], r_c)   # e₃ᵀ [r_c]× = (e₃ × r_c)ᵀ
    u = g @ landmark.J_px
    var = float(v @ P_ss @ v + u @ landmark.M_px @ u)
    return float(np.sqrt(max(var, 0.0))) / float(r_c[2])


def epipolar_gate(var_a: float, var_b: float, f: float, sigma_theta: float, frames: int) -> float:
    """``EPIPOLAR_SIGMAS √(σ_a² + σ_b² + frames f² σ_θ²)`` px (``var_a``, ``var_b`` px², ``σ_θ`` the
    odometry's rotation σ per frame, ``frames`` between the views)."""
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
    """The waiting views and their pairing, one per filter; ``sigma_theta``: odometry rotation σ per
    frame (rad). The views' poses are the filter's clones, passed in at each step."""

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
        """Pair the waiting views (poses in ``poses``) with ``frame``'s unassociated ``features``
        seen from ``(R, p)``; return at most ``room`` landmarks with parallax enough and spread
        small enough (``pose_covariance(j)``: the (12, 12) joint covariance of the current pose and
        frame j's), each with its feature. Views still waiting and unpaired features wait."""
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
        """Index of the free feature paired with ``view``, or -1 (the gate takes the largest free
        pixel variance)."""
        if not free:
            return -1
        gate = epipolar_gate(np.linalg.eigvalsh(view.R_px)[-1], float(np.max(var[free])), self.K.f,
                             self.sigma_theta, frame - view.frame)
        j = two_view_candidates(view.uv, uv[free], *pose_a, R, p, self.K, gate)
        return free[j] if j >= 0 else -1
