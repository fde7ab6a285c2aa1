"""Obstacle footprints of a static MuJoCo scene: how far a point of the floor is from every solid.

Shared by the planar track's ``PlanarScene`` and the lines track's ``LineScene`` (both assign
``clearance = footprint.clearance``): the scripted loops and the default ellipse are checked
against it.
"""

from __future__ import annotations

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np


def clearance(scene, xy: np.ndarray) -> np.ndarray:
    """Distance (n,) from points (n, 2) to the nearest obstacle's footprint (the horizontal
    section of every box, cylinder, sphere or capsule that rises above the floor; 0 inside).
    ``scene`` is anything with a compiled ``model`` and its ``data`` after ``mj_forward``."""
    xy = np.atleast_2d(np.asarray(xy, float))
    best = np.full(len(xy), np.inf)
    m, d = scene.model, scene.data
    for g in range(m.ngeom):
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE or d.geom_xpos[g, 2] + m.geom_rbound[g] <= 0.01:
            continue   # the floor and anything sunk in it
        best = np.minimum(best, footprint_distance(m.geom_type[g], m.geom_size[g], d.geom_xpos[g, :2],
                                                   d.geom_xmat[g].reshape(3, 3)[:2, :2], xy))
    return best


def footprint_distance(kind: int, size: np.ndarray, centre: np.ndarray, rot: np.ndarray,
                       xy: np.ndarray) -> np.ndarray:
    """Distance from points to one geom's footprint, the geom standing upright: a box's
    rectangle ``|q| ≤ (sx, sy)`` with ``q = R_xyᵀ (p − c)``, a disc of radius ``size[0]`` else."""
    q = (xy - centre) @ rot
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return np.linalg.norm(np.maximum(np.abs(q) - size[:2], 0.0), axis=1)
    return np.maximum(np.linalg.norm(q, axis=1) - size[0], 0.0)
