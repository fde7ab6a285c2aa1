"""Belief of the planar track (open loop): the camera track's knobs read in the plane. Pose
``(x, y, θ)`` with Σ_pose = diag(σ_p², σ_p², σ_θ²), map ``Σ_L = σ_l² I + σ_c² (11ᵀ ⊗ I₂)``, error
drawn from ``k² Σ``; candidates are the mapped posts predicted in the lidar's range and field of
view, ``P = H Σ Hᵀ`` with the range-bearing Jacobians; measurements are the frame's detections plus
``clutter`` uniform over range × bearing.
"""

from __future__ import annotations

import numpy as np

from ..models.range_bearing import wrap
from .config import BeliefConfig

RANGE_MARGIN = 1.05   # candidates out to 5 % beyond max range: a post the estimate puts just outside may be seen


def planar_pose_covariance(cfg: BeliefConfig) -> np.ndarray:
    """Σ_pose (3, 3) of ``(x, y, θ)``, heading in radians."""
    return np.diag([cfg.sigma_position ** 2] * 2 + [np.deg2rad(cfg.sigma_rotation) ** 2])


def map_covariance(n: int, cfg: BeliefConfig, dim: int = 2) -> np.ndarray:
    """Σ_L (dim·n, dim·n) = σ_l² I + σ_c² (11ᵀ ⊗ I_dim), the map covariance the belief reports."""
    cov = cfg.sigma_landmark ** 2 * np.eye(dim * n)
    if cfg.sigma_common > 0:
        cov += cfg.sigma_common ** 2 * np.kron(np.ones((n, n)), np.eye(dim))
    return cov


def sample_planar_estimate(pose: np.ndarray, posts: np.ndarray, cfg: BeliefConfig,
                           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(pose estimate (3,), map estimate (L, 2))``: truth plus an error drawn from ``k² Σ``."""
    k = cfg.miscalibration
    e_pose = rng.normal(0.0, 1.0, 3) * np.sqrt(np.diag(planar_pose_covariance(cfg))) * k
    e_map = rng.normal(0.0, cfg.sigma_landmark * k, posts.shape) + rng.normal(0.0, cfg.sigma_common * k, 2)
    est = np.asarray(pose, dtype=np.float64) + e_pose
    est[2] = wrap(est[2])
    return est, posts + e_map


def open_loop_pose(pose: np.ndarray, cfg: BeliefConfig, seed: int, frame: int) -> np.ndarray:
    """The open loop's pose estimate (3,) of ``frame``: the first draw of
    ``default_rng([seed, frame, 101])``, as the planar and lines problems make it, so pictures show
    the pose the problem was predicted from."""
    rng = np.random.default_rng([seed, frame, 101])
    return sample_planar_estimate(pose, np.zeros((0, 2)), cfg, rng)[0]


def in_sensor_view(zhat: np.ndarray, max_range: float, fov: float) -> np.ndarray:
    """Predictions inside the sensor's range (with ``RANGE_MARGIN``) and field of view (n,)."""
    return (zhat[:, 0] <= RANGE_MARGIN * max_range) & (np.abs(zhat[:, 1]) <= fov / 2 + 1e-12)


def clutter_detections(rng: np.random.Generator, count: int, R: np.ndarray, max_range: float,
                       fov: float) -> tuple[np.ndarray, np.ndarray]:
    """``count`` false detections uniform over ``[0, max_range] × [−fov/2, fov/2]`` with the noise
    ``R`` (2, 2) the detector would report."""
    z = np.column_stack([rng.uniform(0.0, max_range, count), rng.uniform(-fov / 2, fov / 2, count)])
    return z, np.repeat(np.asarray(R, dtype=np.float64)[None], count, axis=0)


def nominal_noise(R_frame: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """The noise a clutter detection reports: the frame's element-wise median, else ``fallback``;
    where that median is not positive definite (correlated α, r), the frame's covariance of median
    log-determinant."""
    if not len(R_frame):
        return fallback
    median = np.median(R_frame, axis=0)
    if np.linalg.eigvalsh(median).min() > 0:
        return median
    logdet = np.linalg.slogdet(R_frame)[1]
    return np.asarray(R_frame[np.argsort(logdet)[len(logdet) // 2]])


