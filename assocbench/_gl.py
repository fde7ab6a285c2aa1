"""Pick the OpenGL backend before mujoco is imported: EGL works headless, osmesa/glfw do not."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
