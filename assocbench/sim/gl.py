"""Load MuJoCo under the user's offscreen GL backend (``MUJOCO_GL``, ``egl`` unless set) once,
before any simulator module imports it; ``from assocbench import Problem`` never loads MuJoCo."""

from __future__ import annotations

import os
import sys

from .. import _runtime  # noqa: F401  (MUJOCO_GL=egl unless the user chose)

GL_ERROR = ""   # why mujoco could not load the MUJOCO_GL backend; FrameRenderer reports it


def _load_mujoco() -> None:
    """Import mujoco under the user's ``MUJOCO_GL``; a backend that cannot load would make
    ``import assocbench`` itself raise, so load it without GL instead (all but rendering works) and
    keep the reason in ``GL_ERROR``."""
    global GL_ERROR
    if "mujoco" in sys.modules:
        return
    platform = os.environ.get("PYOPENGL_PLATFORM")
    try:
        import mujoco  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - each backend fails its own way (RuntimeError, AttributeError, ...)
        GL_ERROR = f"{type(exc).__name__}: {exc}".replace("\n", " ").strip()
        for name in [m for m in sys.modules if m == "mujoco" or m.startswith("mujoco.")]:
            del sys.modules[name]
        user = os.environ["MUJOCO_GL"]
        os.environ["MUJOCO_GL"] = "disable"   # mujoco reads it once, at import
        try:
            import mujoco  # noqa: F401,F811
        finally:
            os.environ["MUJOCO_GL"] = user   # child processes try the user's choice again
            if platform is None:              # the failed backend set it for PyOpenGL
                os.environ.pop("PYOPENGL_PLATFORM", None)
            else:
                os.environ["PYOPENGL_PLATFORM"] = platform


_load_mujoco()
