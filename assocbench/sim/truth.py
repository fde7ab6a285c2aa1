"""Ground truth: which landmarks are really visible, and which feature images which landmark."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import _runtime  # noqa: F401
from ..validation import in_range, one_of, validate_fields
from .camera import Intrinsics, project
from .scene import Scene

import mujoco  # noqa: E402


@dataclass(frozen=True)
class TruthConfig:
    """Settings of the truth labelling; all enter the sequence cache key.

    gate_px: a feature is labelled with a landmark when each is the other's nearest and
        they are closer than this (px).
    margin_px: landmarks projecting closer than this to the border count as out of view.
    max_view_angle: landmarks seen more obliquely than this (deg from the normal) are not
        facing the camera.
    occlusion: ``ray`` (``mj_multiRay`` towards each landmark) or ``depth`` (rendered z-depth
        at the projection; one extra render pass).
    """

    gate_px: float = field(default=2.0, metadata=in_range(0, 50, lo_open=True))
    margin_px: float = field(default=8.0, metadata=in_range(0))
    max_view_angle: float = field(default=75.0, metadata=in_range(0, 90, lo_open=True))
    occlusion: str = field(default="ray", metadata=one_of("ray", "depth"))

    def __post_init__(self) -> None:
        validate_fields(self, "truth")


def occluded_by_ray(scene: Scene, p: np.ndarray, points: np.ndarray, tol: float = 0.02) -> np.ndarray:
    """True where the first surface hit from ``p`` towards a point lies before it (by > tol m)."""
    vec = points - p
    dist = np.linalg.norm(vec, axis=1)
    unit = np.ascontiguousarray((vec / dist[:, None]).ravel())
    hit = np.empty(len(points))
    geom = np.empty(len(points), np.int32)
    mujoco.mj_multiRay(scene.model, scene.data, p.astype(np.float64), unit, None, True, -1,
                       geom, hit, None, len(points), float(dist.max() + 1.0))
    return (hit >= 0) & (hit < dist - tol)


def occluded_by_depth(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, tol: float = 0.02) -> np.ndarray:
    """True where the rendered depth at the rounded projection is nearer than the point."""
    cols = np.clip(np.rint(uv[:, 0]).astype(int), 0, depth.shape[1] - 1)
    rows = np.clip(np.rint(uv[:, 1]).astype(int), 0, depth.shape[0] - 1)
    return depth[rows, cols] < z - tol


def visibility(scene: Scene, R: np.ndarray, p: np.ndarray, K: Intrinsics, cfg: TruthConfig,
               depth: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True projections (L, 2) and two masks of landmarks in front, facing and unoccluded:
    ``imaged`` (projecting anywhere in the image: features may be labelled with them) and
    ``visible`` (also at least ``margin_px`` inside the border: a detector should find them)."""
    uv, z = project(scene.landmarks, R, p, K)
    to_cam = p - scene.landmarks
    cos_view = np.einsum("ij,ij->i", scene.normals, to_cam) / np.linalg.norm(to_cam, axis=1)
    uv_safe = np.nan_to_num(uv, nan=-1e9)
    imaged = (z > 1e-6) & K.in_image(uv_safe) & (cos_view > np.cos(np.deg2rad(cfg.max_view_angle)))
    idx = np.flatnonzero(imaged)
    if len(idx):
        if cfg.occlusion == "depth" and depth is not None:
            blocked = occluded_by_depth(depth, uv[idx], z[idx])
        else:
            blocked = occluded_by_ray(scene, p, scene.landmarks[idx])
        imaged[idx[blocked]] = False
    return uv, imaged, imaged & K.in_image(uv_safe, cfg.margin_px)


def label_features(features: np.ndarray, uv: np.ndarray, imaged: np.ndarray, gate_px: float) -> np.ndarray:
    """Landmark index of each feature (m,) or -1: mutual nearest neighbours within ``gate_px``
    among the landmarks ``imaged`` (unoccluded, facing, in the image)."""
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
