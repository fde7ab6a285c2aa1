"""The camera track's association problem without rendering, with known truth: for tests and benchmarks."""

from __future__ import annotations

import numpy as np

from ...association.problem import Problem
from ...belief.config import BeliefConfig, sample_estimate
from ...models.camera import Intrinsics
from ...models.pinhole import predict_bundle
from ...models.synthetic import observe
from .belief import bundle_covariance


def camera_problem(rng: np.random.Generator, n: int = 40, p_detect: float = 0.8, clutter_ratio: float = 0.2,
                   sigma_position: float = 0.05, sigma_rotation_deg: float = 1.0, sigma_landmark: float = 0.03,
                   sigma_common: float = 0.03, sigma_pixel: float = 1.0) -> tuple[Problem, np.ndarray]:
    """The camera track without rendering: ``n`` landmarks 2-8 m before a 640x480 camera, the
    rendered benchmark's belief (P = J Σ Jᵀ with pose, landmark and common-mode errors),
    measurements from the true state."""
    K = Intrinsics.from_fovy(640, 480, 60.0)
    cfg = BeliefConfig(sigma_position=sigma_position, sigma_rotation=sigma_rotation_deg,
                       sigma_landmark=sigma_landmark, sigma_common=sigma_common, sigma_pixel=sigma_pixel)
    depth = rng.uniform(2.0, 8.0, n)
    pix = rng.uniform([20, 20], [620, 460], (n, 2))
    landmarks = np.column_stack([(pix - [K.cx, K.cy]) * depth[:, None] / K.f, depth])  # camera = world frame
    R, p = np.eye(3), np.zeros(3)
    R_hat, p_hat, l_hat = sample_estimate(R, p, landmarks, cfg, rng)
    zhat, J_pose, J_l, _ = predict_bundle(R_hat, p_hat, l_hat, K)
    z_true = predict_bundle(R, p, landmarks, K)[0] + rng.normal(0.0, sigma_pixel, (n, 2))
    n_clutter = int(round(clutter_ratio * n))
    z, truth = observe(rng, z_true, p_detect, rng.uniform([0, 0], [640, 480], (n_clutter, 2)))
    R_meas = np.repeat((sigma_pixel**2 * np.eye(2))[None], len(z), axis=0)
    return Problem(z, R_meas, zhat, bundle_covariance(J_pose, J_l, cfg), volume=K.area), truth
