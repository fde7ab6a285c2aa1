"""What the planar and lines tracks share: a robot in the plane with a 2-D lidar. ``LidarTrack`` is
their common part; the frame source is ``plane_source``, the loop's sensor ``plane_sensor``. Light
to import."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any, ClassVar

import numpy as np

from .base import FeatureTrack
from .capabilities import GymEnv, RunFrame, gym_envs_of

# the paths of a robot in the plane (``sim.planar_trajectory``), as ``assocbench list`` shows them
PLANE_TRAJECTORIES = [
    ("loop", "a shipped planar or lines scene's own path (laps, start), its default"),
    ("ellipse", "an ellipse around the posts (lines: the wall faces) clear of every obstacle (laps, start, scale), "
                "a user MJCF's default"),
    ("waypoints", "the user's own path through the x, y [, heading] waypoints (m, deg) of a CSV or YAML file "
                  "(file), checked to keep 0.5 m from every obstacle"),
]


class LidarTrack(FeatureTrack):
    """The planar and lines tracks' common part: the robot's paths, a cached sequence of scans and
    their features, a closed loop (``PlanarSensor``'s EKF), a top view per frame, Gymnasium envs. A
    subclass says what its map and features look like and makes its sequence."""

    code: ClassVar[tuple[str, ...]] = ()   # the package folders a cached sequence depends on
    maker: ClassVar[str] = ""              # ``module:function`` that makes its sequence from a spec

    def lidar_source(self, spec: Any) -> Any:
        """The sequence of ``spec`` as a frame source, cached under the track's name."""
        from .plane_source import lidar_source

        return lidar_source(self.name, spec, self.code, self.maker)

    def trajectories(self) -> list[tuple[str, str]]:
        return PLANE_TRAJECTORIES

    def gym_envs(self) -> tuple[GymEnv, ...]:
        return gym_envs_of(self.scenes(), ("open", "loop"))

    # --- pictures: the shared top view, with what each track's map and features look like -------
    def frame_picture(self, run: Any, index: int) -> tuple[np.ndarray, str]:
        from . import plane_pictures

        return plane_pictures.frame_picture(self, run, index)

    def run_pictures(self, run: Any, source: Any, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
        from . import plane_pictures

        return plane_pictures.run_pictures(self, run, frames)

    def picture_map(self, seq: Any) -> dict[str, np.ndarray]:
        """The map as the top view draws it: ``{"posts": (L, 2)}`` or ``{"walls": (S, 2, 2)}`` (m)."""
        raise NotImplementedError

    def feature_shapes(self, seq: Any, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """Frame ``k``'s features (the sensor's, then clutter) in the robot frame:
        ``{"points": (m, 2)}`` or ``{"segments": (m, 2, 2)}``."""
        raise NotImplementedError

    def unseen(self, seq: Any, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        """The detectable ``landmarks`` the sensor did not detect, as ``PlaneFrame`` draws them."""
        return {}

    def estimated_map(self, estimator: Any) -> tuple[np.ndarray, np.ndarray]:
        """The filter's map to draw: landmarks (k, 2) and which are confirmed; none by default."""
        return np.zeros((0, 2)), np.zeros(0, bool)

    def picture_note(self) -> str:
        """One line under the top view's key: what it does not draw."""
        return ""


