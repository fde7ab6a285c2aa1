"""The tracks: ``base.py`` the ``Track`` interface, ``registry.py``, ``plane*.py`` what the lidar
tracks share, and one folder per track."""

from ..sim import gl  # noqa: F401  (mujoco is loaded under MUJOCO_GL before a track imports it)
