"""Offscreen rendering of a scene from a camera pose with ``mujoco.Renderer``."""

from __future__ import annotations

import os
import warnings

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from ..errors import UserError
from ..models.camera import CV_TO_MUJOCO, Intrinsics
from ..models.depth_frame import NO_GEOM
from . import gl  # loads mujoco under MUJOCO_GL; GL_ERROR says if the backend could not load
from .scene import Scene
from .settings import MAX_SIDE, MIN_SIDE, check_msaa  # noqa: F401  (the renderer checks sizes; callers import them here)

FAR_SHARE = 0.999   # a depth within 0.1 % of the far plane is "nothing hit" (float32 readback)
GEOM_TYPE = int(mujoco.mjtObj.mjOBJ_GEOM)   # a plain int: numpy compares an enum object element by element


GL_CHECK = "MUJOCO_GL=egl python -c \"import mujoco; mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'))\""


def _gl_error(reason: str) -> UserError:
    """One line saying that offscreen rendering failed, why, and how to get EGL working."""
    gl = os.environ.get("MUJOCO_GL", "")
    if gl.strip().lower() == "egl":
        fix = ("EGL is installed with your GPU driver or with Mesa (Debian/Ubuntu: apt install libegl1 "
               "libgl1-mesa-dri)")
    else:
        fix = "assocbench renders headless with EGL: unset MUJOCO_GL or set MUJOCO_GL=egl"
    return UserError(f"offscreen rendering does not work with MUJOCO_GL={gl} ({reason}); {fix}; "
                     f"check it with: {GL_CHECK}")


def _gl_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """``mujoco.Renderer``, or a one-line ``UserError`` when the GL backend gives no context."""
    if gl.GL_ERROR:   # the backend did not even load; mujoco was loaded without GL
        raise _gl_error(gl.GL_ERROR)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # noqa: BLE001 - FatalError, ImportError, AttributeError by backend
            failure = f"{type(exc).__name__}: {exc}".replace("\n", " ").strip()
        else:
            failure = ""
    if failure:
        raise _gl_error("; ".join([*[str(w.message) for w in caught][:1], failure]))   # glfw's warning says why
    for w in caught:   # a context was made after all: pass the warnings on
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return renderer


def _geometry_only() -> mujoco.MjvOption:
    """Visual options with every site group hidden: a depth sensor sees geoms only (``lm*`` sites
    are drawn as spheres)."""
    option = mujoco.MjvOption()
    option.sitegroup[:] = 0
    return option


class FrameRenderer:
    """Renders RGB, and on request metric z-depth and segmentation ``(H, W, 2) [objid, objtype]``
    (each a full extra pass); ``render_depth`` renders depth and geom segmentation alone. ``msaa``:
    offscreen multisamples (None: the scene's ``<quality offsamples>``; 0 is fastest, with harder
    edges).
    """

    def __init__(self, scene: Scene, width: int = 640, height: int = 480, msaa: int | None = None) -> None:
        check_msaa(msaa)
        max_w, max_h = scene.offscreen
        if width < MIN_SIDE or height < MIN_SIDE:
            raise UserError(f"resolution {width}x{height} is too small: use at least {MIN_SIDE}x{MIN_SIDE}")
        if width > max_w or height > max_h:
            raise UserError(
                f"resolution {width}x{height} exceeds the offscreen buffer {max_w}x{max_h} of scene "
                f"{scene.name!r}: lower it or raise <visual><global offwidth offheight> in the MJCF"
            )
        self.scene = scene
        self._depth_option = _geometry_only()
        self.K = Intrinsics.from_fovy(width, height, scene.fovy)
        self.far = float(scene.model.vis.map.zfar * scene.model.stat.extent)   # depth of "nothing hit"
        quality = scene.model.vis.quality
        own = quality.offsamples
        quality.offsamples = own if msaa is None else msaa   # read when the GL context is made
        try:
            self._renderer = _gl_renderer(scene.model, width, height)
        finally:
            quality.offsamples = own

    def place_camera(self, R: np.ndarray, p: np.ndarray) -> None:
        """Move the scene camera to pose ``(R, p)`` (OpenCV convention, camera-to-world)."""
        model, data, cid = self.scene.model, self.scene.data, self.scene.camera_id
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R @ CV_TO_MUJOCO).ravel())
        model.cam_pos[cid] = p
        model.cam_quat[cid] = quat
        mujoco.mj_camlight(model, data)

    def render(self, R: np.ndarray, p: np.ndarray, depth: bool = False,
               segmentation: bool = False) -> dict[str, np.ndarray]:
        """Images of one frame: ``rgb`` (H, W, 3) uint8, optional ``depth`` and ``segmentation``."""
        self.place_camera(R, p)
        r = self._renderer
        r.update_scene(self.scene.data, camera=self.scene.camera_id)
        out = {"rgb": r.render().copy()}
        if depth:
            r.enable_depth_rendering()
            out["depth"] = r.render().copy()
            r.disable_depth_rendering()
        if segmentation:
            r.enable_segmentation_rendering()
            out["segmentation"] = r.render().copy()
            r.disable_segmentation_rendering()
        return out

    def render_depth(self, R: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Depth and geom segmentation of one frame without the RGB pass: ``depth`` (H, W) metric z,
        NaN where nothing is hit; ``geom`` (H, W) the geom id, ``NO_GEOM`` (-1) for none. Sites
        hidden."""
        self.place_camera(R, p)
        r = self._renderer
        r.update_scene(self.scene.data, camera=self.scene.camera_id, scene_option=self._depth_option)
        r.enable_depth_rendering()
        depth = r.render().astype(np.float64)
        r.disable_depth_rendering()
        r.enable_segmentation_rendering()
        seg = r.render()
        r.disable_segmentation_rendering()
        depth[~((depth > 0) & (depth < FAR_SHARE * self.far))] = np.nan   # the far plane, as ``sequence.depth_at``
        geom = np.where(seg[..., 1] == GEOM_TYPE, seg[..., 0], NO_GEOM).astype(np.int64)
        return depth, geom

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
