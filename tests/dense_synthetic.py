"""Synthetic depth frames for the dense track's tests (no renderer): axis-aligned boxes ray-cast
analytically at 320x240, turned into ``DepthFrame``s with the shared vertex and normal maps.

The room corner is a 4 x 4 m floor, two 2.5 m walls meeting at the origin and a 0.5 m crate: every
pose is constrained (three plane orientations plus the crate's edges). ``single_wall`` is a
degenerate scene: one plane leaves two translations and one rotation unconstrained.
"""

from __future__ import annotations

import numpy as np

from assocbench.models.camera import Intrinsics, look_at
from assocbench.models.depth_frame import NO_GEOM, DepthFrame, normal_map, vertex_map

K320 = Intrinsics.from_fovy(320, 240, 45.0)

# boxes (B, 2, 3): lower and upper corner; the geom id of a box is its index
ROOM = np.array([
    [[0.0, 0.0, -0.1], [4.0, 4.0, 0.0]],      # 0 floor
    [[-0.1, 0.0, 0.0], [0.0, 4.0, 2.5]],      # 1 wall x = 0
    [[0.0, -0.1, 0.0], [4.0, 0.0, 2.5]],      # 2 wall y = 0
    [[0.9, 1.1, 0.0], [1.4, 1.6, 0.5]],       # 3 crate
])
WALL = np.array([[[-0.1, -20.0, -20.0], [0.0, 20.0, 20.0]]])   # one plane x = 0, larger than any view

ROOM_EYE, ROOM_TARGET = np.array([2.0, 1.9, 1.1]), np.array([0.8, 0.9, 0.4])
WALL_EYE, WALL_TARGET = np.array([2.0, 0.3, 1.0]), np.array([0.0, -0.2, 0.8])


def pose_at(eye, target) -> tuple[np.ndarray, np.ndarray]:
    """Camera-to-world pose (R, t) of a camera at ``eye`` looking at ``target`` (z up)."""
    return look_at(np.asarray(eye, float), np.asarray(target, float)), np.asarray(eye, float).copy()


def cast(boxes: np.ndarray, R: np.ndarray, t: np.ndarray, K: Intrinsics = K320):
    """Ray-cast every pixel: z-depth (H, W) (NaN: nothing hit), geom (H, W) and the cosine between
    the view ray and the surface normal (H, W), by the slab method (the camera is outside all boxes)."""
    u = (np.arange(K.width) - K.cx) / K.f
    v = (np.arange(K.height) - K.cy) / K.f
    rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], 1.0), axis=-1) @ R.T   # world, camera z = 1
    depth = np.full((K.height, K.width), np.inf)
    geom = np.full((K.height, K.width), NO_GEOM)
    cos = np.full((K.height, K.width), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        for b, (lo, hi) in enumerate(boxes):
            t1, t2 = (lo - t) / rays, (hi - t) / rays
            near, far = np.minimum(t1, t2), np.maximum(t1, t2)
            enter, leave = near.max(axis=-1), far.min(axis=-1)
            hit = (enter > 0) & (enter <= leave) & (enter < depth)
            axis = near.argmax(axis=-1)
            d_axis = np.take_along_axis(rays, axis[..., None], -1)[..., 0]
            depth[hit], geom[hit] = enter[hit], b
            cos[hit] = np.abs(d_axis[hit]) / np.linalg.norm(rays[hit], axis=-1)
    depth[~np.isfinite(depth)] = np.nan
    return depth, geom, cos


def render(boxes: np.ndarray, R: np.ndarray, t: np.ndarray, K: Intrinsics = K320, sigma_base: float = 0.0,
           sigma_quad: float = 0.0, grazing_deg: float | None = None, rng=None) -> DepthFrame:
    """A ``DepthFrame`` of ``boxes`` from pose (R, t): noise-free unless ``sigma_*`` (axial noise
    σ(z) = σ_base + σ_quad z², the sensor's model), pixels viewed more than ``grazing_deg`` from the
    surface normal dropped; truth from the noise-free depth."""
    depth, geom, cos = cast(boxes, R, t, K)
    true_points = vertex_map(depth, K) @ R.T + t
    measured = depth.copy()
    if sigma_base or sigma_quad:
        rng = np.random.default_rng([0, 17]) if rng is None else rng
        measured = measured + (sigma_base + sigma_quad * depth ** 2) * rng.standard_normal(depth.shape)
    if grazing_deg is not None:
        measured[cos < np.cos(np.deg2rad(grazing_deg))] = np.nan
    V = vertex_map(measured, K)
    return DepthFrame(K, measured, V, normal_map(V), true_points, geom, R.copy(), t.copy())


def room_frame(eye=ROOM_EYE, target=ROOM_TARGET, **noise) -> DepthFrame:
    return render(ROOM, *pose_at(eye, target), **noise)


def wall_frame(eye=WALL_EYE, target=WALL_TARGET, **noise) -> DepthFrame:
    return render(WALL, *pose_at(eye, target), **noise)


def source_set(frame: DepthFrame):
    """The frame's valid pixels as a source set in world coordinates: points, normals (n, 3),
    true_points (n, 3), geom (n,)."""
    ok = frame.valid
    return (frame.vertices[ok] @ frame.R.T + frame.t, frame.normals[ok] @ frame.R.T,
            frame.true_points[ok], frame.geom[ok])


def rotation(axis, deg: float) -> np.ndarray:
    """Rodrigues rotation of ``deg`` degrees about ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    th = np.deg2rad(deg)
    return np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k


def perturb(R: np.ndarray, t: np.ndarray, rot_deg: float, trans: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) rotated by ``rot_deg`` about a random axis (through the camera centre) and moved by
    ``trans`` metres in a random direction."""
    axis, step = rng.standard_normal(3), rng.standard_normal(3)
    return rotation(axis, rot_deg) @ R, t + trans * step / np.linalg.norm(step)


def pose_error(R, t, R_true, t_true) -> tuple[float, float]:
    """(translation error m, rotation error deg) between two camera-to-world poses."""
    c = np.clip((np.trace(R.T @ R_true) - 1) / 2, -1.0, 1.0)
    return float(np.linalg.norm(t - t_true)), float(np.degrees(np.arccos(c)))


def correct(pairs, true_points: np.ndarray, geom: np.ndarray, frame: DepthFrame, tol: float = 0.01) -> np.ndarray:
    """Per pair: same geom and true positions within ``tol`` metres."""
    fg = frame.geom.reshape(-1)[pairs.pixel]
    ft = frame.true_points.reshape(-1, 3)[pairs.pixel]
    return (geom[pairs.source] == fg) & (np.linalg.norm(true_points[pairs.source] - ft, axis=1) < tol)
