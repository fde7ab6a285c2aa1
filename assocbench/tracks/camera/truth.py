"""Ground truth: which landmarks are really visible, and which feature images which landmark."""

from __future__ import annotations

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from ...models.camera import Intrinsics, project
from ...sim.normals import RENDERED_GROUPS
from ...sim.scene import Scene
from .settings import TruthConfig


def occluded_by_ray(scene: Scene, p: np.ndarray, points: np.ndarray, tol: float = 0.02) -> np.ndarray:
    """True where the first rendered surface from ``p`` towards a point lies before it (by > tol m);
    geoms the renderer does not draw (collision geoms) hide nothing."""
    vec = points - p
    dist = np.linalg.norm(vec, axis=1)
    unit = np.ascontiguousarray((vec / dist[:, None]).ravel())
    hit = np.empty(len(points))
    geom = np.empty(len(points), np.int32)
    mujoco.mj_multiRay(scene.model, scene.data, p.astype(np.float64), unit, RENDERED_GROUPS, True, -1,
                       geom, hit, None, len(points), float(dist.max() + 1.0))
    return (hit >= 0) & (hit < dist - tol)


def occluded_by_depth(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, tol: float = 0.02,
                      slope: np.ndarray | float = 0.0) -> np.ndarray:
    """True where the rendered depth at the rounded projection is nearer than the point by more than
    ``tol`` plus ``slope`` (m/px: how fast the landmark's own surface recedes,
    ``surface_depth_slope``), capped at half the point's depth. Without the slope an oblique wall
    would occlude itself."""
    cols = np.clip(np.rint(uv[:, 0]).astype(int), 0, depth.shape[1] - 1)
    rows = np.clip(np.rint(uv[:, 1]).astype(int), 0, depth.shape[0] - 1)
    return depth[rows, cols] < z - np.minimum(tol + slope, 0.5 * z)


def surface_depth_slope(normals: np.ndarray, uv: np.ndarray, z: np.ndarray, R: np.ndarray,
                        K: Intrinsics) -> np.ndarray:
    """Change of z-depth per pixel (m/px) of the planes through points at ``uv``, depth ``z``
    with world normals (k, 3): along ray ``r = ((u - cx)/f, (v - cy)/f, 1)`` the plane
    ``n_c · x = n_c · (z r)`` lies at depth ``z(u, v) = (n_c · z r) / (n_c · r)``, so
    ``|∇z| = z |(n_x, n_y)| / (f |n_c · r|)`` with ``n_c = Rᵀ n``."""
    n_c = normals @ R
    rays = np.column_stack([(uv[:, 0] - K.cx) / K.f, (uv[:, 1] - K.cy) / K.f, np.ones(len(uv))])
    along = np.abs(np.einsum("ij,ij->i", n_c, rays))
    with np.errstate(divide="ignore"):
        return z * np.hypot(n_c[:, 0], n_c[:, 1]) / (K.f * along)


def visibility(scene: Scene, R: np.ndarray, p: np.ndarray, K: Intrinsics, cfg: TruthConfig,
               depth: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """True projections (L, 2) and the mask (L,) of the landmarks really imaged: in front
    (``z > 0``), in the image, the patch's front towards the camera (``n · (p - l) > 0``, however
    oblique: the X-junction still images precisely) and nothing between (``mj_ray`` or the rendered
    depth). Detection is ``label_features``' business, the estimate's view limit the belief's
    (``max_view_angle``).
    """
    uv, z = project(scene.landmarks, R, p, K)
    facing = np.einsum("ij,ij->i", scene.normals, p - scene.landmarks) > 0
    visible = (z > 1e-6) & K.in_image(np.nan_to_num(uv, nan=-1e9)) & facing
    idx = np.flatnonzero(visible)
    if len(idx):
        if cfg.occlusion == "depth" and depth is not None:
            slope = surface_depth_slope(scene.normals[idx], uv[idx], z[idx], R, K)
            blocked = occluded_by_depth(depth, uv[idx], z[idx], slope=slope)
        else:
            blocked = occluded_by_ray(scene, p, scene.landmarks[idx])
        visible[idx[blocked]] = False
    return uv, visible


def label_features(features: np.ndarray, uv: np.ndarray, imaged: np.ndarray, gate_px: float) -> np.ndarray:
    """Landmark index of each feature (m,) or -1: mutual nearest neighbours within ``gate_px``
    among the ``imaged`` landmarks (``visibility``'s mask): the detector found its corner."""
    labels = np.full(len(features), -1, dtype=np.int64)
    idx = np.flatnonzero(imaged)
    if not len(features) or not len(idx):
        return labels
    d = np.linalg.norm(features[:, None, :] - uv[idx][None, :, :], axis=2)
    nearest_lm = d.argmin(axis=1)
    nearest_ft = d.argmin(axis=0)
    for i, k in enumerate(nearest_lm):
        if nearest_ft[k] == i and d[i, k] <= gate_px:
            labels[i] = idx[k]
    return labels
