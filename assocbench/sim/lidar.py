"""A 2-D lidar: one ``mj_multiRay`` call casts every beam of a scan in the horizontal plane, from
the robot's ``(x, y)`` at ``height``. Beam ``i`` points at the robot-frame angle ``α_i`` (full
circle: ``2π i / B`` from the heading, counter-clockwise; else evenly over ``[−fov/2, fov/2]``) and
returns ``r_i = d_i + ε_i``, ``ε_i ~ N(0, σ_r²)`` (``d_i`` the true distance), or NaN: nothing
within ``max_range``, a reading beyond it, or a random ``dropout``.
"""

from __future__ import annotations

from typing import Protocol

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from .scan import Scan
from .settings import LidarConfig


class RayScene(Protocol):
    """What a scan is cast in: a compiled MuJoCo model and its data (a ``PlanarScene``, a ``LineScene``)."""

    model: mujoco.MjModel
    data: mujoco.MjData


def cast(scene: RayScene, origin: np.ndarray, world_angles: np.ndarray,
         cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """True distances (k,) (``inf``: nothing within ``cutoff``) and hit geom ids (k,) (−1) of
    horizontal rays from ``origin`` at ``world_angles``, one ``mj_multiRay`` call."""
    k = len(world_angles)
    vec = np.zeros((k, 3))
    vec[:, 0], vec[:, 1] = np.cos(world_angles), np.sin(world_angles)
    dist, geom = np.empty(k), np.empty(k, np.int32)
    mujoco.mj_multiRay(scene.model, scene.data, origin, vec.ravel(), None, True, -1, geom, dist, None, k, cutoff)
    beyond = (dist < 0) | (dist > cutoff)
    return np.where(beyond, np.inf, dist), np.where(beyond, -1, geom)


def scan(scene: RayScene, pose: np.ndarray, cfg: LidarConfig, rng: np.random.Generator) -> Scan:
    """Scan from ``pose = (x, y, θ)``: ``r_i = d_i + ε_i`` or NaN. B normals then B uniforms are
    drawn whatever the scene, so frames stay aligned."""
    angles = cfg.angles()
    origin = np.array([pose[0], pose[1], cfg.height], float)
    dist, geom = cast(scene, origin, angles + pose[2], cfg.max_range)
    noise = rng.normal(0.0, 1.0, len(angles)) * cfg.sigma_range
    dropped = rng.random(len(angles)) < cfg.dropout
    ranges = dist + noise
    ranges[dropped | ~(ranges <= cfg.max_range)] = np.nan   # ~(<=) also catches inf
    return Scan(angles, ranges, geom.astype(int), cfg.full_circle, dist)
