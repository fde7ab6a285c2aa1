"""A camera's path through a scene (trajectory, parameters, frames, image shape), shared by every
track that renders, so a scene's path is one thing whichever track renders along it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError
from .scene import Scene, resolve_scene_path
from .trajectory import TRAJECTORIES, make_trajectory, rig_for
from .waypoints import read_waypoints, user_keyframes, waypoint_path

# a shipped scene's default trajectory when a run names none; a user MJCF's is the circle
DEFAULT_TRAJECTORY = {"room": "circle", "checkerboard": "line", "corridor": "line", "bays": "line", "crates": "circle"}


@dataclass(frozen=True)
class CameraPath:
    """The path of ``frames`` camera poses through ``scene`` (``width`` / ``height`` set the field
    of view the rig keeps the landmarks in)."""

    scene: str
    trajectory: str | None = None            # None: the scene's default
    trajectory_params: dict = field(default_factory=dict)
    frames: int = 40
    seed: int = 0
    width: int = 640
    height: int = 480

    def resolved_trajectory(self) -> str:
        """The trajectory's name (the scene's default when None), checked, a waypoint file included,
        before anything runs."""
        name = self.trajectory or DEFAULT_TRAJECTORY.get(Path(self.scene).stem, "circle")
        if name not in TRAJECTORIES:
            raise UserError(f"unknown trajectory {name!r}: choose one of {', '.join(TRAJECTORIES)}")
        if name == "waypoints":
            read_waypoints(waypoint_path(self.trajectory_params, resolve_scene_path(self.scene).parent))
        return name

    def poses(self, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
        """Camera rotations (N, 3, 3) and positions (N, 3) along the path in ``scene``."""
        rig = rig_for(scene.landmarks, scene.normals, scene.fovy, self.width / self.height, scene.free_distance)
        name = self.resolved_trajectory()
        params, keys = user_keyframes(name, self.trajectory_params, scene)
        return make_trajectory(name, rig, self.frames, self.seed, keys=keys, **params)
