"""Obstacle footprints of a static MuJoCo scene: how far a floor point is from every solid; the
planar and lines scenes' paths are checked against it (``clearance``).
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
    """Distance (n,) from points (n, 2) to the nearest obstacle's footprint (the horizontal section
    of each solid rising above the floor, a mesh's outline; 0 inside) and that obstacle's geom id.
    ``scene``: a compiled ``model`` and ``data`` after ``mj_forward``."""
    xy = np.atleast_2d(np.asarray(xy, float))
    best, which = np.full(len(xy), np.inf), np.full(len(xy), -1)
    m, d = scene.model, scene.data
    for g in obstacles(scene):
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            dist = polygon_distance(mesh_outline(m, d, g), xy)
        else:
            dist = footprint_distance(m.geom_type[g], m.geom_size[g], d.geom_xpos[g, :2],
                                      d.geom_xmat[g].reshape(3, 3)[:2, :2], xy)
        closer = dist < best
        best[closer], which[closer] = dist[closer], g
    return best, which


def clearance(scene, xy: np.ndarray) -> np.ndarray:
    """Distance (n,) from points (n, 2) to the nearest obstacle's footprint (``nearest_obstacle``)."""
    return nearest_obstacle(scene, xy)[0]


def extent(scene) -> tuple[np.ndarray, np.ndarray]:
    """Corners ``(lo, hi)`` of the axis-aligned rectangle around every obstacle's footprint."""
    m, d = scene.model, scene.data
    points = []
    for g in obstacles(scene):
        centre, size = d.geom_xpos[g, :2], m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            corners = np.array([[sx, sy] for sx in (-1, 1) for sy in (-1, 1)]) * size[:2]
            points.append(centre + corners @ d.geom_xmat[g].reshape(3, 3)[:2, :2].T)
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            points.append(mesh_outline(m, d, g))
        else:
            points.append(centre + np.array([[-1, -1], [1, 1]]) * size[0])
    stacked = np.vstack(points)
    return stacked.min(axis=0), stacked.max(axis=0)


def footprint_distance(kind: int, size: np.ndarray, centre: np.ndarray, rot: np.ndarray,
                       xy: np.ndarray) -> np.ndarray:
    """Distance to one upright geom's footprint: a box's rectangle ``|q| ≤ (sx, sy)``,
    ``q = R_xyᵀ (p − c)``, else a disc of radius ``size[0]``."""
    q = (xy - centre) @ rot
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return np.linalg.norm(np.maximum(np.abs(q) - size[:2], 0.0), axis=1)
    return np.maximum(np.linalg.norm(q, axis=1) - size[0], 0.0)


def mesh_outline(m, d, g: int) -> np.ndarray:
    """The footprint of mesh geom ``g``: the counter-clockwise convex hull of its world vertices
    ``c + R v``. Its ``geom_size`` is an inertia box about axes that need not be upright, so no
    footprint."""
    start, count = m.mesh_vertadr[m.geom_dataid[g]], m.mesh_vertnum[m.geom_dataid[g]]
    world = d.geom_xpos[g] + m.mesh_vert[start:start + count].astype(float) @ d.geom_xmat[g].reshape(3, 3).T
    return convex_hull(world[:, :2])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (k, 2) of points, counter-clockwise (Andrew's monotone chain); two points on a
    line, one for one."""
    pts = np.unique(np.asarray(points, float), axis=0)   # sorted by x, then y
    if len(pts) <= 2:
        return pts

    def half(seq) -> list:
        out: list = []
        for p in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]
    return np.array(half(pts) + half(pts[::-1]))


def _turn(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """``(a − o) × (b − o)``: positive when o, a, b turn counter-clockwise."""
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def polygon_distance(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Distance (n,) from points (n, 2) to a convex polygon (k, 2), counter-clockwise (0 inside);
    a segment or a point when k is 2 or 1."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    e = b - a                                                      # (k, 2) edges
    w = xy[:, None, :] - a[None]                                   # (n, k, 2)
    t = np.clip(np.einsum("nkj,kj->nk", w, e) / np.maximum(np.einsum("kj,kj->k", e, e), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(w - t[..., None] * e[None], axis=2).min(axis=1)
    inside = np.all(e[None, :, 0] * w[..., 1] - e[None, :, 1] * w[..., 0] >= 0, axis=1) if len(polygon) >= 3 else False
    return np.where(inside, 0.0, dist)
