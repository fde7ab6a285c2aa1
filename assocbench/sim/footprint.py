"""Obstacle footprints of a static MuJoCo scene: how far a point of the floor is from every solid.

Shared by the planar track's ``PlanarScene`` and the lines track's ``LineScene`` (both assign
``clearance = footprint.clearance``): the scripted loops, the default ellipse and a user's
waypoint path are checked against it.
"""

from __future__ import annotations

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

CLEARANCE = 0.5      # m from the robot's centre to any obstacle's footprint (a 0.3 m robot + margin)


def obstacles(scene) -> list[int]:
    """Geom ids of the obstacles: every geom but the floor and anything sunk in it."""
    m, d = scene.model, scene.data
    return [g for g in range(m.ngeom)
            if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE and d.geom_xpos[g, 2] + m.geom_rbound[g] > 0.01]


def nearest_obstacle(scene, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (n,) from points (n, 2) to the nearest obstacle's footprint (the horizontal
    section of every box, cylinder, sphere or capsule that rises above the floor; 0 inside) and
    that obstacle's geom id (n,). ``scene`` is anything with a compiled ``model`` and its
    ``data`` after ``mj_forward``."""
    xy = np.atleast_2d(np.asarray(xy, float))
    best, which = np.full(len(xy), np.inf), np.full(len(xy), -1)
    m, d = scene.model, scene.data
    for g in obstacles(scene):
        dist = footprint_distance(m.geom_type[g], m.geom_size[g], d.geom_xpos[g, :2],
                                  d.geom_xmat[g].reshape(3, 3)[:2, :2], xy)
        closer = dist < best
        best[closer], which[closer] = dist[closer], g
    return best, which


def clearance(scene, xy: np.ndarray) -> np.ndarray:
    """Distance (n,) from points (n, 2) to the nearest obstacle's footprint (``nearest_obstacle``)."""
    return nearest_obstacle(scene, xy)[0]


def extent(scene) -> tuple[np.ndarray, np.ndarray]:
    """The corners ``(lo, hi)`` (2,) of the axis-aligned rectangle around every obstacle's
    footprint: a box's four corners ``c ± R_xy (±s_x, ±s_y)``, a round geom's ``c ± r``."""
    m, d = scene.model, scene.data
    points = []
    for g in obstacles(scene):
        centre, size = d.geom_xpos[g, :2], m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            corners = np.array([[sx, sy] for sx in (-1, 1) for sy in (-1, 1)]) * size[:2]
            points.append(centre + corners @ d.geom_xmat[g].reshape(3, 3)[:2, :2].T)
        else:
            points.append(centre + np.array([[-1, -1], [1, 1]]) * size[0])
    stacked = np.vstack(points)
    return stacked.min(axis=0), stacked.max(axis=0)


def footprint_distance(kind: int, size: np.ndarray, centre: np.ndarray, rot: np.ndarray,
                       xy: np.ndarray) -> np.ndarray:
    """Distance from points to one geom's footprint, the geom standing upright: a box's
    rectangle ``|q| ≤ (sx, sy)`` with ``q = R_xyᵀ (p − c)``, a disc of radius ``size[0]`` else."""
    q = (xy - centre) @ rot
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return np.linalg.norm(np.maximum(np.abs(q) - size[:2], 0.0), axis=1)
    return np.maximum(np.linalg.norm(q, axis=1) - size[0], 0.0)
