"""What a lidar track's sequence shares (planar and lines): the path of its spec, and the
poses in the plane read as 3-D rotations and positions (for TUM files and 3-D metrics)."""

from __future__ import annotations

import numpy as np

from ..models.se2 import rz
from .planar_trajectory import scripted
from .scene import resolve_scene_path
from .waypoints import waypoint_digest


class ScenePath:
    """The path of a lidar track's spec (``scene``, ``trajectory``): shared by the planar and lines tracks."""

    def resolved_trajectory(self) -> str:
        """The trajectory's name: the given one, else the scene's default (``loop`` for a shipped
        scene, ``ellipse`` for a user MJCF)."""
        return self.trajectory or ("loop" if scripted(resolve_scene_path(self.scene)) else "ellipse")

    def path_digest(self) -> str | None:
        """A hash of the waypoint file's bytes when the path is ``waypoints`` (the sequence cache's
        key holds it, so an edited file is driven again), else None."""
        return waypoint_digest(self.resolved_trajectory(), self.trajectory_params, self.scene)


class PosesInPlane:
    """A lidar track's sequence's ``poses`` (N, 3) ``(x, y, θ)``, also as 3-D rotations and positions."""

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def rotations(self) -> np.ndarray:
        """(N, 3, 3) ``Rz(θ)``: the poses as 3-D rotations (for TUM files and 3-D metrics)."""
        return rz(self.poses[:, 2])

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) ``(x, y, 0)``."""
        return np.column_stack([self.poses[:, :2], np.zeros(len(self.poses))])
