"""A 2-D lidar: one ``mj_multiRay`` call casts every beam of a scan in the horizontal plane.

The lidar sits at the robot's origin ``(x, y)``, at ``height`` above the floor. Beam ``i`` points
at the robot-frame angle ``α_i``: over a full circle ``α_i = 2π i / B`` (beam 0 along the heading,
counter-clockwise), over a sector of ``fov`` the beams spread evenly over ``[−fov/2, fov/2]``.
A beam returns ``r_i = d_i + ε_i``, ``ε_i ~ N(0, σ_r²)`` (``d_i``: the true distance to the first
surface), or nothing (NaN): when nothing lies within ``max_range``, when the measured range falls
beyond it, or, with probability ``dropout``, at random.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..validation import in_range, one_of, validate_fields
from .cache import storable
from .planar_scene import PlanarScene

if TYPE_CHECKING:
    from .line_scene import LineScene

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs

MODES = ("lidar", "geometric")


@dataclass(frozen=True)
class LidarConfig:
    """Lidar settings (section ``lidar``).

    mode: ``lidar`` (ray-cast scans and circle fits) or ``geometric`` (true range and bearing of
        every unoccluded post plus noise: fast and idealised).
    beams: beams per scan. fov_deg: field of view (deg), centred on the heading.
    max_range: farthest return (m). sigma_range: σ of each beam's range noise (m).
    sigma_bearing_deg: σ of the bearing noise in geometric mode (deg).
    dropout: probability that a beam (geometric mode: a post) returns nothing.
    height: height of the scan plane above the floor (m).
    """

    mode: str = field(default="lidar", metadata=one_of(*MODES))
    beams: int = field(default=720, metadata=in_range(1, 100000))
    fov_deg: float = field(default=360.0, metadata=in_range(0, 360, lo_open=True))
    max_range: float = field(default=10.0, metadata=in_range(0, 1000, lo_open=True))
    # at least 1e-6 m: a range σ of 1e-300 squares to 0, a singular R (the worker crashed)
    sigma_range: float = field(default=0.01, metadata=in_range(1e-6, 10))
    # at least 1e-6 deg: a bearing σ below it squares to a covariance under numpy's tolerance
    sigma_bearing_deg: float = field(default=0.5, metadata=in_range(1e-6, 180))
    dropout: float = field(default=0.0, metadata=in_range(0, 1, hi_open=True))
    height: float = field(default=0.5, metadata=in_range(0, 100, lo_open=True))

    def __post_init__(self) -> None:
        validate_fields(self, "lidar")

    @property
    def fov(self) -> float:
        """Field of view (rad)."""
        return float(np.deg2rad(self.fov_deg))

    @property
    def full_circle(self) -> bool:
        return self.fov_deg >= 360.0

    def angles(self) -> np.ndarray:
        """Beam angles (B,) in the robot frame, wrapped to (−π, π]."""
        if self.full_circle:
            a = 2 * np.pi * np.arange(self.beams) / self.beams
        elif self.beams == 1:
            a = np.zeros(1)
        else:
            a = np.linspace(-self.fov / 2, self.fov / 2, self.beams)
        return np.where(a > np.pi, a - 2 * np.pi, a)


@storable
@dataclass
class Scan:
    """One scan. ``geom`` and ``distance`` are the truth: the geom each beam's ray meets first
    within ``max_range`` (−1: none) and how far (``inf``: none), kept even where the return
    dropped out; ``distance`` is None for scans made without it."""

    angles: np.ndarray   # (B,) robot frame (rad)
    ranges: np.ndarray   # (B,) measured (m), NaN: no return
    geom: np.ndarray     # (B,) int, hit geom id or -1
    full_circle: bool = True   # the beams cover 360° (beam B−1 neighbours beam 0)
    distance: np.ndarray | None = None   # (B,) true distance d_i (m), inf: no hit within max_range

    def points(self) -> np.ndarray:
        """Hit points (B, 2) in the robot frame, ``r_i (cos α_i, sin α_i)`` (NaN without return)."""
        return self.ranges[:, None] * np.column_stack([np.cos(self.angles), np.sin(self.angles)])


def cast(scene: PlanarScene | LineScene, origin: np.ndarray, world_angles: np.ndarray,
         cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """True distances (k,) (``inf``: nothing within ``cutoff``) and hit geom ids (k,) (−1) of
    horizontal rays from ``origin`` (3,) at ``world_angles`` (k,): one ``mj_multiRay`` call
    (its cutoff skips geoms whose bounds lie beyond it, not every hit beyond it)."""
    k = len(world_angles)
    vec = np.zeros((k, 3))
    vec[:, 0], vec[:, 1] = np.cos(world_angles), np.sin(world_angles)
    dist, geom = np.empty(k), np.empty(k, np.int32)
    mujoco.mj_multiRay(scene.model, scene.data, origin, vec.ravel(), None, True, -1, geom, dist, None, k, cutoff)
    beyond = (dist < 0) | (dist > cutoff)
    return np.where(beyond, np.inf, dist), np.where(beyond, -1, geom)


def scan(scene: PlanarScene | LineScene, pose: np.ndarray, cfg: LidarConfig, rng: np.random.Generator) -> Scan:
    """Scan from ``pose = (x, y, θ)``: ``r_i = d_i + ε_i`` or NaN (no hit, beyond range, dropout).
    The generator draws B normals then B uniforms whatever the scene, so frames stay aligned."""
    angles = cfg.angles()
    origin = np.array([pose[0], pose[1], cfg.height], float)
    dist, geom = cast(scene, origin, angles + pose[2], cfg.max_range)
    noise = rng.normal(0.0, 1.0, len(angles)) * cfg.sigma_range
    dropped = rng.random(len(angles)) < cfg.dropout
    ranges = dist + noise
    ranges[dropped | ~(ranges <= cfg.max_range)] = np.nan   # ~(<=) also catches inf
    return Scan(angles, ranges, geom.astype(int), cfg.full_circle, dist)
