"""The planar track: a robot among identical posts, a 2-D lidar, circle fits, range-bearing."""

from __future__ import annotations

import importlib.util

import numpy as np

from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...sim.lidar import LidarConfig
from ...sim.planar_scene import load_planar_scene
from ...sim.scenegen.planar import PLANAR_SCENES
from ...validation import free_mapping, typed_section
from ..base import SMOOTHED_ATE_GUARD, EnvSlots, GuardedMetric, SceneMarks, first_line, register_track
from ..plane import LidarTrack, PlanarSensor
from .belief import make_planar_problem
from .estimator import make_planar_estimator
from .post_detect import PostDetectorConfig
from .sequence import PlanarSequence, PlanarSequenceSpec, make_planar_sequence

# the sources a cached sequence depends on: shared simulation and belief, measurement models, this track
CODE = ("sim", "models", "belief", "tracks/planar")


class PlanarTrack(LidarTrack):
    """Scenes whose landmarks are ``lm*`` cylinder geoms (posts)."""

    name = "planar"
    summary = "a 2-D lidar among identical posts, circle fits, range-bearing; EKF-SLAM or GTSAM iSAM2"
    ci_suites = ("planar_ci", "planar_isam2_ci")
    suites = ("planar", "planar_ci", "planar_isam2_ci")
    spec_type = PlanarSequenceSpec
    gym_modes = ("open", "loop")
    code = CODE

    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.landmark_geoms > 0

    def check_metrics(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """Accuracy, and in the closed loop the filtered and (where the baseline has it) the
        smoothed ATE: the iSAM2 back end is a smoother."""
        return super().check_metrics(loop) + ((SMOOTHED_ATE_GUARD,) if loop else ())

    def ci_suite_skipped(self, name: str) -> str | None:
        if name == "planar_isam2_ci" and importlib.util.find_spec("gtsam") is None:
            return "gtsam is not installed (pip install 'assocbench[gtsam]')"
        return None

    def section_types(self) -> dict[str, type]:
        return {"lidar": LidarConfig, "posts": PostDetectorConfig}

    def sequence_spec(self, cfg: dict, estimator: EstimatorConfig) -> PlanarSequenceSpec:
        """Lidar scans along the scene's path and the posts detected in them (``lidar``, ``posts``).
        The iSAM2 back end's package is looked for here, before anything compiles or runs."""
        if estimator.name == "isam2" and cfg["loop"] and importlib.util.find_spec("gtsam") is None:
            raise UserError("estimator.name: isam2 needs the gtsam package: pip install 'assocbench[gtsam]' "
                            "(from a clone: pip install '.[gtsam]')")
        seq = PlanarSequenceSpec(scene=cfg["scene"], trajectory=cfg["trajectory"],
                                 trajectory_params=free_mapping(cfg, "trajectory_params"), frames=cfg["frames"],
                                 seed=cfg["seed"], lidar=typed_section(LidarConfig, cfg["lidar"], "lidar"),
                                 posts=typed_section(PostDetectorConfig, cfg["posts"], "posts"))
        seq.check()
        return seq

    def make_sequence(self, spec):
        return make_planar_sequence(spec)

    def problems(self, seq: PlanarSequence, belief, seed: int) -> list:
        return [make_planar_problem(seq, k, belief, seed) for k in range(len(seq))]

    def make_estimator(self, seq: PlanarSequence, cfg: EstimatorConfig, belief, seed: int):
        return make_planar_estimator(seq, cfg, belief, seed)

    def loop_sensor(self, seq: PlanarSequence, belief, est: EstimatorConfig, seed: int) -> PlanarSensor:
        return PlanarSensor(seq, belief, est, seed)

    def env_slots(self, spec) -> EnvSlots:
        """N: every post of the scene; M: the most posts a scan can yield (geometric mode: one per
        post; lidar: one per ``posts.min_points`` beams, each beam in one fit) plus ``belief.clutter``."""
        seq, posts = spec.sequence, len(load_planar_scene(spec.sequence.scene).posts)
        detections = posts if seq.lidar.mode == "geometric" else seq.lidar.beams // seq.posts.min_points
        return EnvSlots(posts, detections + spec.belief.clutter)

    def shipped_scenes(self) -> dict[str, str]:
        return {name: first_line(build.__doc__) for name, build in PLANAR_SCENES.items()}

    def landmarks(self, scene: str) -> np.ndarray:
        return load_planar_scene(scene).posts

    def picture_map(self, seq: PlanarSequence) -> dict[str, np.ndarray]:
        return {"posts": seq.posts}

    def feature_shapes(self, seq: PlanarSequence, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """Each detection ``(r, φ)`` at ``r (cos φ, sin φ)``."""
        z = np.asarray(z, float).reshape(-1, 2)
        return {"points": z[:, :1] * np.column_stack([np.cos(z[:, 1]), np.sin(z[:, 1])])}

    def unseen(self, seq: PlanarSequence, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        return {"unseen_posts": seq.posts[landmarks]}

    def estimated_map(self, estimator) -> tuple[np.ndarray, np.ndarray]:
        """The filter's posts and which are confirmed."""
        xy = np.asarray(estimator.landmarks, float).reshape(-1, 2)
        return xy, np.asarray(estimator.book.confirmed, bool).reshape(len(xy))


register_track(PlanarTrack)
