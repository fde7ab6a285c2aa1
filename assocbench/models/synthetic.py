"""Synthetic association problems with known truth and no rendering (tests, benchmarks):
``lattice_problem`` (ambiguity on demand) and ``range_bearing_problem``. Measurements are drawn from
the model the problem reports, so gating theory holds.
"""

from __future__ import annotations

import numpy as np

from ..association.compatibility import wrap_angles
from ..association.problem import NO_MATCH, Problem


def observe(rng, z_true: np.ndarray, p_detect: float, clutter: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Detected measurements (shuffled, clutter included) and the true association."""
    n = len(z_true)
    detected = np.flatnonzero(rng.uniform(size=n) < p_detect)
    z = np.vstack([z_true[detected], clutter])
    perm = rng.permutation(len(z))
    z = z[perm]
    truth = np.full(n, NO_MATCH, dtype=np.int64)
    where = np.argsort(perm)  # position of original row r in the shuffled array
    truth[detected] = where[: len(detected)]
    return z, truth


def lattice_problem(rng: np.random.Generator, n: int = 20, spacing: float = 30.0, sigma_common: float = 10.0,
                    sigma_independent: float = 2.0, sigma_meas: float = 1.0, p_detect: float = 0.9,
                    n_clutter: int = 5, cols: int = 5, elongation: float = 1.0,
                    scale_spread: float = 1.0) -> tuple[Problem, np.ndarray]:
    """Landmarks on a ``cols``-wide lattice of pixel ``spacing``,
    ``P = σ_c² (11ᵀ ⊗ I) + blockdiag(Q_j)``: a common shift plus random ellipses (axes
    ``σ_i·elongation``, ``σ_i``) scaled log-uniformly in ``[1/scale_spread, scale_spread]``.
    """
    idx = np.arange(n)
    zhat = np.column_stack([idx % cols, idx // cols]).astype(float) * spacing + 50.0
    P = sigma_common**2 * np.kron(np.ones((n, n)), np.eye(2))
    scales = np.exp(rng.uniform(-1.0, 1.0, n) * np.log(scale_spread)) * sigma_independent
    for j, theta in enumerate(rng.uniform(0, np.pi, n)):
        rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
        P[2 * j:2 * j + 2, 2 * j:2 * j + 2] += rot @ np.diag([elongation**2, 1.0]) @ rot.T * scales[j] ** 2
    err = np.linalg.cholesky(P) @ rng.normal(size=2 * n)
    z_true = zhat + err.reshape(n, 2) + rng.normal(0.0, sigma_meas, (n, 2))
    lo, hi = zhat.min(axis=0) - spacing, zhat.max(axis=0) + spacing
    z, truth = observe(rng, z_true, p_detect, rng.uniform(lo, hi, (n_clutter, 2)))
    R = np.repeat((sigma_meas**2 * np.eye(2))[None], len(z), axis=0)
    return Problem(z, R, zhat, P, volume=float(np.prod(hi - lo))), truth


def _range_bearing(pose: np.ndarray, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``h = (|l - p|, atan2(l - p) - θ)`` and its Jacobian w.r.t. ``[x, y, θ, l_x, l_y]`` (n, 2, 5)."""
    delta = landmarks - pose[:2]
    q = np.einsum("ij,ij->i", delta, delta)
    r = np.sqrt(q)
    h = np.column_stack([r, np.arctan2(delta[:, 1], delta[:, 0]) - pose[2]])
    dx, dy = delta[:, 0], delta[:, 1]
    J = np.zeros((len(r), 2, 5))
    J[:, 0, :] = np.column_stack([-dx / r, -dy / r, np.zeros_like(r), dx / r, dy / r])
    J[:, 1, :] = np.column_stack([dy / q, -dx / q, -np.ones_like(r), -dy / q, dx / q])
    return wrap_angles(h, (1,)), J


def range_bearing_problem(rng: np.random.Generator, n: int = 40, p_detect: float = 0.8, clutter_ratio: float = 0.2,
                          sigma_pose: tuple[float, float] = (0.3, np.deg2rad(3.0)), sigma_landmark: float = 0.2,
                          sigma_meas: tuple[float, float] = (0.1, np.deg2rad(1.0)), extent: float = 20.0
                          ) -> tuple[Problem, np.ndarray]:
    """A robot at the origin heading +x observing ``n`` landmarks within ``extent``;
    ``e_l_j = e_pose,xy + ε_j``, so P has pose-landmark cross terms.
    """
    pose = np.array([0.0, 0.0, 0.0])
    radius = extent * np.sqrt(rng.uniform(0.05, 1.0, n))
    angle = rng.uniform(-np.pi, np.pi, n)
    landmarks = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    s_xy, s_th = sigma_pose
    dim = 3 + 2 * n
    T = np.zeros((dim, dim))  # error = T · standard normal
    T[:3, :3] = np.diag([s_xy, s_xy, s_th])
    T[3:, :2] = np.tile(np.eye(2) * s_xy * 0.7, (n, 1))
    T[3:, 3:] = np.eye(2 * n) * sigma_landmark
    Sigma = T @ T.T
    h, J = _range_bearing(pose, landmarks)
    H = np.zeros((2 * n, dim))
    for j in range(n):
        H[2 * j:2 * j + 2, :3] = J[j, :, :3]
        H[2 * j:2 * j + 2, 3 + 2 * j:5 + 2 * j] = J[j, :, 3:]
    P = H @ Sigma @ H.T
    err = T @ rng.normal(size=dim)
    true_h, _ = _range_bearing(pose + err[:3], landmarks + err[3:].reshape(n, 2))
    z_true = wrap_angles(true_h + rng.normal(0.0, 1.0, (n, 2)) * sigma_meas, (1,))
    n_clutter = int(round(clutter_ratio * n))
    clutter = np.column_stack([rng.uniform(0, extent, n_clutter), rng.uniform(-np.pi, np.pi, n_clutter)])
    z, truth = observe(rng, z_true, p_detect, clutter)
    R = np.repeat(np.diag(np.square(sigma_meas))[None], len(z), axis=0)
    return Problem(z, R, h, 0.5 * (P + P.T), volume=extent * 2 * np.pi, angular=(1,)), truth
