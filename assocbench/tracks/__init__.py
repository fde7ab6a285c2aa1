"""The tracks of the benchmark: ``base.py`` the ``Track`` interface and registry, ``plane.py``
what the lidar tracks share, and one folder per track (``camera``, ``planar``, ``lines``,
``dense``) with its scene convention, sensor, sequence, belief, estimators, metrics and pictures."""

from ..sim import gl  # noqa: F401  (mujoco is loaded under MUJOCO_GL before a track imports it)
