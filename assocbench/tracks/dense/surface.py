"""Distance from points to the true surfaces of a MuJoCo scene: the dense track's map error.

Each rendered geom (groups 0–2) is an analytic surface; with ``q = R_gᵀ (p − c_g)`` the unsigned
distance to its *surface* is:

* sphere: ``| |q| − r |``; capsule: ``| |q − (0, 0, clamp(q_z, −h, h))| − r |``;
* cylinder: ``a = ρ − r``, ``b = |q_z| − h``: ``√(max(a,0)² + max(b,0)²)`` outside, ``min(−a, −b)``
  inside;
* box: ``a = |q| − s``: ``‖max(a, 0)‖`` outside, ``min(−a)`` inside;
* plane: the finite rectangle MuJoCo renders (half-size 0: infinite),
  ``√(max(|q_x| − s_x, 0)² + max(|q_y| − s_y, 0)² + q_z²)``: a point beyond a wall's edge is an
  error.

Other geom types are a one-line ``UserError``. The least distance over geoms, per point, in one
compiled pass with a bounding-sphere skip: memory O(n).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np
from numba import njit

from ...errors import UserError
from ...sim.normals import RENDERED_GROUPS

PLANE, SPHERE, CAPSULE, CYLINDER, BOX = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_SPHERE),
                                         int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER),
                                         int(mujoco.mjtGeom.mjGEOM_BOX))
ANALYTIC = {PLANE: "plane", SPHERE: "sphere", CAPSULE: "capsule", CYLINDER: "cylinder", BOX: "box"}


@njit(cache=True)
def _geom_distance(kind, s, qx, qy, qz):
    """Unsigned distance from the local point q to one geom's surface (module docstring)."""
    if kind == 0:     # plane (PLANE)
        dx = max(abs(qx) - s[0], 0.0) if s[0] > 0 else 0.0
        dy = max(abs(qy) - s[1], 0.0) if s[1] > 0 else 0.0
        return np.sqrt(dx * dx + dy * dy + qz * qz)
    if kind == 2:     # sphere
        return abs(np.sqrt(qx * qx + qy * qy + qz * qz) - s[0])
    if kind == 3:     # capsule: distance to the axis segment, minus the radius
        dz = qz - min(max(qz, -s[1]), s[1])
        return abs(np.sqrt(qx * qx + qy * qy + dz * dz) - s[0])
    if kind == 5:     # cylinder
        a, b = np.sqrt(qx * qx + qy * qy) - s[0], abs(qz) - s[1]
        if a > 0 or b > 0:
            a, b = max(a, 0.0), max(b, 0.0)
            return np.sqrt(a * a + b * b)
        return min(-a, -b)
    ax, ay, az = abs(qx) - s[0], abs(qy) - s[1], abs(qz) - s[2]   # box
    if ax > 0 or ay > 0 or az > 0:
        ax, ay, az = max(ax, 0.0), max(ay, 0.0), max(az, 0.0)
        return np.sqrt(ax * ax + ay * ay + az * az)
    return -max(ax, max(ay, az))


@njit(cache=True, inline="always")
def _distance_to(g, kinds, sizes, centres, rots, px, py, pz):
    """Distance from the world point p to geom ``g``'s surface: ``q = R_gᵀ (p − c_g)``, then ``_geom_distance``."""
    dx, dy, dz = px - centres[g, 0], py - centres[g, 1], pz - centres[g, 2]
    r = rots[g]   # q = Rᵀ (p − c): row-major xmat, columns are the geom's axes
    qx = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
    qy = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
    qz = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
    return _geom_distance(kinds[g], sizes[g], qx, qy, qz)


@njit(cache=True)
def _distance_kernel(points, kinds, sizes, centres, rots, bounds, out):
    """``out[i] = min_g distance(points[i], g)``, skipping g when
    ``|p − c_g|² > (best + bound_g)²``; the previous point's nearest geom goes first, so most skip
    at once."""
    hint = 0
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        best = _distance_to(hint, kinds, sizes, centres, rots, px, py, pz) if kinds.shape[0] else np.inf
        nearest = hint
        for g in range(kinds.shape[0]):
            dx, dy, dz = px - centres[g, 0], py - centres[g, 1], pz - centres[g, 2]
            reach = best + bounds[g]     # |p − c| ≥ reach: no nearer than best; squared, with a margin
            if g == hint or dx * dx + dy * dy + dz * dz > reach * reach * (1.0 + 1e-9):   # for rounding
                continue
            dist = _distance_to(g, kinds, sizes, centres, rots, px, py, pz)
            if dist < best:
                best, nearest = dist, g
        hint = nearest
        out[i] = best if np.isfinite(px + py + pz) else np.nan


def _bound(kind: int, s: np.ndarray) -> float:
    """Radius of a sphere round the geom's centre that holds its whole surface (inf: unbounded)."""
    if kind == PLANE:
        return float(np.hypot(s[0], s[1])) if s[0] > 0 and s[1] > 0 else np.inf
    if kind == SPHERE:
        return float(s[0])
    if kind == CAPSULE:
        return float(s[0] + s[1])
    if kind == CYLINDER:
        return float(np.hypot(s[0], s[1]))
    return float(np.linalg.norm(s))


def _model_data(scene) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """(model, data) of a Scene-like object or a bare ``MjModel`` (posed at qpos0)."""
    if isinstance(scene, mujoco.MjModel):
        data = mujoco.MjData(scene)
        mujoco.mj_forward(scene, data)
        return scene, data
    if hasattr(scene, "model") and hasattr(scene, "data"):
        return scene.model, scene.data
    raise UserError(f"surface_distance: expected a scene (with .model and .data) or a mujoco.MjModel, "
                    f"got {type(scene).__name__}")


def surface_geoms(scene, geoms: Sequence[int] | None = None) -> tuple[np.ndarray, ...]:
    """The kernel's tables of the rendered geoms (or of ``geoms``); a UserError for a geom without a
    closed form."""
    m, d = _model_data(scene)
    if geoms is None:
        ids = [g for g in range(m.ngeom) if RENDERED_GROUPS[min(int(m.geom_group[g]), 5)]]
    else:
        ids = [int(g) for g in np.atleast_1d(np.asarray(geoms, dtype=np.int64))]
        bad = [g for g in ids if not 0 <= g < m.ngeom]
        if bad:
            raise UserError(f"surface_distance: geom id {bad[0]} is not in the scene "
                            f"(it has {m.ngeom} geoms, 0..{m.ngeom - 1})")
    for g in ids:
        if int(m.geom_type[g]) not in ANALYTIC:
            kind = mujoco.mjtGeom(m.geom_type[g]).name.removeprefix("mjGEOM_").lower()
            name = m.geom(g).name or f"#{g}"
            raise UserError(f"surface_distance: geom {name} has type {kind}; the surface error knows only box, "
                            f"plane, cylinder, sphere and capsule (change its type, or put it in group 3+ so it is "
                            f"not rendered)")
    kinds = np.array([int(m.geom_type[g]) for g in ids], dtype=np.int64)
    sizes = np.array(m.geom_size[ids], dtype=np.float64).reshape(-1, 3)
    bounds = np.array([_bound(k, s) for k, s in zip(kinds, sizes)], dtype=np.float64)
    centres = np.array(d.geom_xpos[ids], dtype=np.float64).reshape(-1, 3)
    rots = np.array(d.geom_xmat[ids], dtype=np.float64).reshape(-1, 3, 3)
    return kinds, sizes, centres, rots, bounds


def surface_distance(points: np.ndarray, scene, geoms: Sequence[int] | None = None) -> np.ndarray:
    """Distance (n,) from points (n, 3) to the nearest rendered geom's surface (or ``geoms``'); NaN
    for a non-finite point, inf with no geom. ``scene``: a ``Scene`` or an ``MjModel``."""
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise UserError(f"surface_distance: points must be an (n, 3) array, got shape {pts.shape}")
    tables = surface_geoms(scene, geoms)
    out = np.empty(len(pts))
    _distance_kernel(np.ascontiguousarray(pts), *tables, out)
    return out


def warm_surface() -> None:
    """Compile (or load from numba's cache) the distance kernel on one point and one box."""
    _distance_kernel(np.zeros((1, 3)), np.array([BOX], np.int64), np.ones((1, 3)), np.zeros((1, 3)),
                     np.eye(3)[None].copy(), np.array([np.sqrt(3.0)]), np.empty(1))
