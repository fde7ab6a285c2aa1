"""What every track's simulation shares: scene loading, rendering, ray casting, trajectories,
odometry, scene generation. Importing it loads MuJoCo under the chosen GL backend (``gl.py``)."""

from . import gl  # noqa: F401  (before any module here imports mujoco)
