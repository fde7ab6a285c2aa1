"""What the planar and lines tracks share: a robot in the plane with a 2-D lidar. ``LidarTrack``
is their common part as tracks (the robot's paths, the cached sequence); ``PlanarSensor`` reads a frame's detections (their noise is the sensor's) plus clutter,
the planar odometry, and the 3-dof pose error ``[δx, δy, δθ]``; the lines track's sensor is this
one with wall lines ``(α, r)`` for posts."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..belief.config import BeliefConfig, with_clutter_labels
from ..belief.planar import clutter_detections, nominal_noise
from ..estimators.base import FrameData, Motion
from ..estimators.config import EstimatorConfig
from ..models.range_bearing import pose_error as planar_pose_error
from ..models.se2 import compose
from ..scoring.trajectory import nees_or_nan, pose_columns
from ..sim.cache import cached_sequence, load_fields, save_fields, spec_key
from ..sim.odometry import planar_odometry
from . import plane_pictures
from .base import RunFrame, Track

# the paths of a robot in the plane (``sim.planar_trajectory``), as ``assocbench list`` shows them
PLANE_TRAJECTORIES = [
    ("loop", "a shipped planar or lines scene's own path (laps, start), its default"),
    ("ellipse", "an ellipse around the posts (lines: the wall faces) clear of every obstacle (laps, start, scale), "
                "a user MJCF's default"),
    ("waypoints", "the user's own path through the x, y [, heading] waypoints (m, deg) of a CSV or YAML file "
                  "(file), checked to keep 0.5 m from every obstacle"),
]


class LidarTrack(Track):
    """A track of a robot in the plane with a 2-D lidar: its sequence is made by
    ``make_sequence(spec)`` (the scans and what was extracted from them) and kept in the shared
    sequence cache under a key of ``code``, the package folders it depends on."""

    code: ClassVar[tuple[str, ...]] = ()
    pictures = True   # a top view per frame (tracks.plane_pictures)

    def make_sequence(self, spec: Any) -> Any:
        raise self._missing("a sequence")

    def load_sequence(self, spec: Any, cache_dir: Path | None = None, use_cache: bool = True) -> Any:
        """The sequence of ``spec`` from the shared sequence cache (``sim.cache``), else made and stored."""
        return cached_sequence(self.cache_folder(), spec_key(spec, self.code), lambda: self.make_sequence(spec), save_fields,
                               load_fields, cache_dir, use_cache, suffix=".npz")

    def trajectories(self) -> list[tuple[str, str]]:
        return PLANE_TRAJECTORIES

    # --- pictures: the shared top view, with what each track's map and features look like -------
    def frame_picture(self, spec: Any, index: int) -> tuple[np.ndarray, str]:
        return plane_pictures.frame_picture(self, spec, index)

    def run_pictures(self, spec: Any, seq: Any, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
        return plane_pictures.run_pictures(self, spec, frames)

    def picture_map(self, seq: Any) -> dict[str, np.ndarray]:
        """The map as the top view draws it: ``{"posts": (L, 2)}`` or ``{"walls": (S, 2, 2)}`` (m)."""
        raise self._missing("a map to draw")

    def feature_shapes(self, seq: Any, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """Frame ``k``'s features ``z`` (the sensor's, then any clutter) in the robot frame:
        ``{"points": (m, 2)}`` or ``{"segments": (m, 2, 2)}``."""
        raise self._missing("features to draw")

    def unseen(self, seq: Any, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        """The detectable ``landmarks`` the sensor did not detect, as ``PlaneFrame`` draws them."""
        return {}

    def estimated_map(self, estimator: Any) -> tuple[np.ndarray, np.ndarray]:
        """The filter's map to draw: landmarks (k, 2) and which are confirmed (k,); none by
        default (a map of lines, known)."""
        return np.zeros((0, 2)), np.zeros(0, bool)

    def picture_note(self) -> str:
        """One line under the top view's key: what it does not draw."""
        return ""


class PlanarSensor:
    """The planar track: post detections (range, bearing) plus clutter, planar odometry, 3-dof
    pose error ``[δx, δy, δθ]``."""

    nees_dof = 3
    new_landmark_gate = 4.0   # σ: without it a strict gate's misses become duplicates (30 for JCBB on the park)
    clutter = staticmethod(clutter_detections)   # false detections (range, bearing) uniform over the sensor's view

    def __init__(self, seq, belief: BeliefConfig, est: EstimatorConfig, seed: int) -> None:
        self.seq, self.belief, self.est, self.seed = seq, belief, est, seed
        self.dead_reckoning = np.array(seq.poses[0], dtype=np.float64)   # odometry alone, for the figures

    def motion(self, k: int) -> Motion:
        motion = planar_odometry(self.seq.poses, k, self.est, self.seed)
        self.dead_reckoning = compose(self.dead_reckoning, motion.increment)
        return motion

    def frame(self, k: int, in_map: np.ndarray | None) -> tuple[FrameData, np.ndarray]:
        """Frame ``k``'s detections (their noise is the sensor's, already in them) and
        ``belief.clutter`` false detections (``clutter``: uniform over the measurement space)."""
        seq = self.seq
        rng = np.random.default_rng([self.seed, k, 101])
        R = seq.R[k].reshape(-1, 2, 2)
        cz, cR = self.clutter(rng, self.belief.clutter, nominal_noise(R, seq.nominal_R), seq.max_range, seq.fov)
        data = FrameData(np.vstack([seq.z[k].reshape(-1, 2), cz]), np.concatenate([R, cR]))
        return data, with_clutter_labels(seq.labels[k], self.belief.clutter, in_map)

    def state_columns(self, f, k: int) -> dict:
        seq = self.seq
        err = planar_pose_error(seq.poses[k], f.pose)
        return {**pose_columns("est_", f.R, f.p), **pose_columns("true_", seq.rotations[k], seq.positions[k]),
                "pos_err": float(np.linalg.norm(err[:2])), "rot_err_deg": float(np.rad2deg(abs(err[2]))),
                "nees": nees_or_nan(err, f.pose_covariance), "nees_dof": self.nees_dof,
                "odo_x": float(self.dead_reckoning[0]), "odo_y": float(self.dead_reckoning[1])}
