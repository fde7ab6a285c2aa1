"""Load a planar scene: a shipped name (``park``) or an MJCF whose posts are ``lm*`` cylinder geoms
of one radius (the camera track marks landmarks with ``lm*`` *sites*, the lines track walls with
``lw*`` boxes). Every geom is static: the lidar's rays start at the pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from ..errors import UserError
from . import footprint
from .scene import LANDMARK_PREFIX, Scene, mjcf_error, resolve_scene_path

RADIUS_TOLERANCE = 1e-6   # m: posts whose radii differ by more than this are not identical


@dataclass
class PlanarScene:
    """A compiled planar scene and its posts (indices follow ``post_names``)."""

    name: str
    path: Path
    model: mujoco.MjModel
    data: mujoco.MjData
    posts: np.ndarray          # (L, 2) world centres
    post_names: list[str]
    post_radius: float
    post_geom_ids: np.ndarray  # (L,) geom id of each post

    digest = Scene.digest      # the MJCF text and its neighbouring files (only ``path`` is read)

    clearance = footprint.clearance   # distance (n,) from points (n, 2) to the nearest obstacle

    @property
    def anchors(self) -> np.ndarray:
        """(L, 2) the points the default ellipse is built around: the posts."""
        return self.posts


def _post_ids(model: mujoco.MjModel, path: Path) -> np.ndarray:
    """Geom ids of the ``lm*`` geoms, checked: cylinders, one radius (one-line errors)."""
    names = [model.geom(i).name for i in range(model.ngeom)]
    ids = np.array([i for i, n in enumerate(names) if n.startswith(LANDMARK_PREFIX)], dtype=int)
    if not len(ids):
        raise UserError(f"MJCF {path} has no posts: add cylinder geoms named lm0, lm1... of one radius")
    bad = [names[i] for i in ids if model.geom_type[i] != mujoco.mjtGeom.mjGEOM_CYLINDER]
    if bad:
        raise UserError(f"MJCF {path}: posts must be cylinders, but {', '.join(bad[:5])} "
                        f"{'is not' if len(bad) == 1 else 'are not'} (make them type=\"cylinder\" or rename them)")
    radii = model.geom_size[ids, 0]
    if np.ptp(radii) > RADIUS_TOLERANCE:
        shown = ", ".join(f"{r:g}" for r in np.unique(np.round(radii, 6))[:5])
        raise UserError(f"MJCF {path}: posts must share one radius, found radii {shown} m (rename the "
                        f"odd ones so they do not start with 'lm': they become clutter)")
    return ids


def load_planar_scene(scene: str | Path) -> PlanarScene:
    """Compile a planar scene and extract its ``lm*`` cylinder posts."""
    path = resolve_scene_path(scene)
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except (ValueError, RuntimeError) as exc:
        raise mjcf_error(path, exc) from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ids = _post_ids(model, path)
    return PlanarScene(
        name=path.stem,
        path=path,
        model=model,
        data=data,
        posts=data.geom_xpos[ids, :2].copy(),
        post_names=[model.geom(i).name for i in ids],
        post_radius=float(model.geom_size[ids[0], 0]),
        post_geom_ids=ids,
    )
