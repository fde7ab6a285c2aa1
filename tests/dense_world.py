"""A synthetic depth sensor for the fusion tests (no renderer): a small MJCF world of planes and
boxes, ray-cast per pixel with ``mujoco.mj_multiRay`` (exact ray-geom intersections, the geom id
for free), axial noise ``σ(z) = 0.0012 + 0.0019 z²`` on the z-depth, vertex and normal maps from
the noisy depth (``sim/depth_frame``) and the truth from the noise-free cast."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter

from assocbench import _runtime  # noqa: F401  (MUJOCO_GL before mujoco loads)

# isort: split
import mujoco  # after assocbench: MUJOCO_GL is set before mujoco loads

# isort: split
from assocbench.models.camera import Intrinsics, look_at
from assocbench.models.depth_frame import NO_GEOM, DepthFrame, normal_map, vertex_map

SIGMA_BASE, SIGMA_QUAD = 0.0012, 0.0019
K320 = Intrinsics.from_fovy(320, 240, 45.0)

# A room corner 2.6 m ahead of the camera (depths 1.4-3.2 m): floor, a back wall, a left wall, a
# tilted box on the floor, and a right wall ("new") that only a camera yawed to the right sees.
# Planes face the camera (their z axis, the side mj_ray hits and the renderer draws).
WORLD_XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" pos="1.3 0 0" size="1.3 2 0.1"/>
    <geom name="back" type="plane" pos="2.6 0 1.5" xyaxes="0 -1 0 0 0 1" size="2 1.5 0.1"/>
    <geom name="left" type="plane" pos="1.3 1.3 1.5" xyaxes="1 0 0 0 0 1" size="1.3 1.5 0.1"/>
    <geom name="crate" type="box" pos="1.7 -0.25 0.3" euler="0 0 30" size="0.3 0.25 0.3"/>
    <geom name="new" type="plane" pos="1.3 -2 1.5" xyaxes="-1 0 0 0 0 1" size="1.3 1.5 0.1"/>
  </worldbody>
</mujoco>
"""


def world() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The compiled world and its data after ``mj_forward``."""
    model = mujoco.MjModel.from_xml_string(WORLD_XML)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def geom_id(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)


def pose(k: int, step: float = 0.01, yaw_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Camera-to-world (R, t) of frame ``k``: wobbling round (0, 0, 1.2) within ±5, ±3, ±1
    ``step``-hundredths of a metre (forward, sideways, up; bounded, so a static scene stays in view),
    looking at the back wall, pitched down about 17°, yawed ``yaw_deg`` to the right."""
    t = np.array([0.0, 0.0, 1.2]) + step * np.array([5 * np.sin(0.23 * k), 3 * np.sin(0.5 * k), np.sin(0.3 * k)])
    yaw = np.deg2rad(-yaw_deg)
    return look_at(t, t + np.array([np.cos(yaw), np.sin(yaw), -0.3])), t


def cast(model, data, R: np.ndarray, t: np.ndarray, K: Intrinsics = K320) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free z-depth (H, W) (NaN: nothing hit) and geom (H, W) (``NO_GEOM``) of each pixel."""
    u = (np.arange(K.width) - K.cx) / K.f
    v = (np.arange(K.height) - K.cy) / K.f
    ray = np.stack(np.broadcast_arrays(u[None, :], v[:, None], 1.0), axis=-1).reshape(-1, 3)
    norm = np.linalg.norm(ray, axis=1)
    dirs = np.ascontiguousarray((ray / norm[:, None]) @ R.T)
    n = len(dirs)
    dist, geom = np.empty(n), np.empty(n, np.int32)
    mujoco.mj_multiRay(model, data, np.asarray(t, float), dirs.ravel(), None, 1, -1, geom, dist, None, n, 1e6)
    hit = dist >= 0
    depth = np.where(hit, dist / norm, np.nan)   # z = distance · (unit ray's z component)
    return depth.reshape(K.height, K.width), np.where(hit, geom, NO_GEOM).reshape(K.height, K.width)


def sigma(z: np.ndarray) -> np.ndarray:
    """Axial noise σ(z) = 0.0012 + 0.0019 z² (m)."""
    return SIGMA_BASE + SIGMA_QUAD * z * z


def smooth_normals(depth: np.ndarray, K: Intrinsics, box: int = 5, step: int = 2) -> np.ndarray:
    """Normals (H, W, 3) as KinectFusion-style pipelines make them, for comparison with the raw
    ``normal_map``: the depth averaged over a ``box``² window (NaN-aware), then
    ``n = (V[v+s,u] − V[v−s,u]) × (V[v,u+s] − V[v,u−s])`` (s = ``step``), normalised, same orientation."""
    ok = np.isfinite(depth)
    num = uniform_filter(np.where(ok, depth, 0.0), box, mode="constant")
    den = uniform_filter(ok.astype(float), box, mode="constant")
    V = vertex_map(np.where(ok, num / np.maximum(den, 1e-12), np.nan), K)
    s, n = step, np.full(V.shape, np.nan)
    c = np.cross(V[2 * s:, s:-s] - V[:-2 * s, s:-s], V[s:-s, 2 * s:] - V[s:-s, :-2 * s])
    norm = np.linalg.norm(c, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n[s:-s, s:-s] = np.where(norm > 0, c / norm, np.nan)
    return n


def frame(model, data, R: np.ndarray, t: np.ndarray, rng: np.random.Generator | None,
          K: Intrinsics = K320, smooth: bool = False) -> DepthFrame:
    """A depth frame seen from (R, t); ``rng`` None: noise-free; ``smooth``: normals from
    ``smooth_normals`` instead of ``normal_map`` (vertices stay raw)."""
    depth_true, geom = cast(model, data, R, t, K)
    true_points = vertex_map(depth_true, K) @ R.T + t
    depth = depth_true if rng is None else depth_true + sigma(depth_true) * rng.standard_normal(depth_true.shape)
    vertices = vertex_map(depth, K)
    normals = smooth_normals(depth, K) if smooth else normal_map(vertices)
    return DepthFrame(K, depth, vertices, normals, true_points, geom, R, t)


def sequence(n: int, seed: int = 0, noise: bool = True, yaw_per_frame: float = 0.0, step: float = 0.01,
             smooth: bool = False):
    """``n`` frames of the world from ``pose(k)``: (model, data, frames)."""
    model, data = world()
    frames = []
    for k in range(n):
        R, t = pose(k, step, yaw_per_frame * k)
        rng = np.random.default_rng([seed, k, 17]) if noise else None
        frames.append(frame(model, data, R, t, rng, smooth=smooth))
    return model, data, frames
