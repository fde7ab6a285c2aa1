"""The lidar's geometric mode: true range and bearing of every visible post plus noise (fast,
idealised: no scan, no fit). A post is visible when within ``max_range``, within the field of view
and first on the ray to its centre (one ``mj_multiRay`` for all); each is detected with probability
``1 − dropout`` as ``z = (r, φ) + ε``, ``ε ~ N(0, diag(σ_r², σ_φ²))``, sorted by bearing so the
order says nothing of identity.
"""

from __future__ import annotations

import numpy as np

from ...models.range_bearing import predict, wrap
from ...sim.lidar import cast
from ...sim.planar_scene import PlanarScene
from ...sim.settings import LidarConfig
from .post_detect import Detections


def true_range_bearing(scene: PlanarScene, pose: np.ndarray) -> np.ndarray:
    """``(r, φ)`` (L, 2) of every post's centre seen from ``pose`` (``models.range_bearing.predict``)."""
    return predict(np.asarray(pose, dtype=np.float64), scene.posts)


def geometric_visible(scene: PlanarScene, pose: np.ndarray, cfg: LidarConfig) -> np.ndarray:
    """(L,) bool: in range, in the field of view, centre unoccluded (the ray meets the post first)."""
    rb = true_range_bearing(scene, pose)
    candidate = (rb[:, 0] <= cfg.max_range) & (cfg.full_circle | (np.abs(rb[:, 1]) <= cfg.fov / 2))
    visible = np.zeros(len(rb), bool)
    idx = np.flatnonzero(candidate)
    if len(idx):
        origin = np.array([pose[0], pose[1], cfg.height], float)
        _, geom = cast(scene, origin, rb[idx, 1] + pose[2], cfg.max_range + 2 * scene.post_radius)
        visible[idx] = geom == scene.post_geom_ids[idx]
    return visible


def geometric_detections(scene: PlanarScene, pose: np.ndarray, cfg: LidarConfig,
                         rng: np.random.Generator) -> tuple[Detections, np.ndarray, np.ndarray]:
    """Detections (by bearing), their labels and the visibility (L,); 2L normals then L uniforms are
    drawn whatever is visible."""
    rb = true_range_bearing(scene, pose)
    visible = geometric_visible(scene, pose, cfg)
    sigma = np.array([cfg.sigma_range, np.deg2rad(cfg.sigma_bearing_deg)])
    noise = rng.normal(0.0, 1.0, rb.shape) * sigma
    kept = visible & (rng.random(len(rb)) >= cfg.dropout)
    labels = np.flatnonzero(kept)
    z = rb[labels] + noise[labels]
    z[:, 1] = wrap(z[:, 1])
    order = np.argsort(z[:, 1], kind="stable")
    R = np.broadcast_to(np.diag(sigma ** 2), (len(labels), 2, 2)).copy()
    return Detections(z[order], R, [np.zeros(0, int)] * len(labels)), labels[order], visible
