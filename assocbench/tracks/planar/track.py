"""The planar track: a robot among identical posts, a 2-D lidar, circle fits, range-bearing. Light
to import."""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np

from ...belief.config import BeliefConfig
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...settings import Schema, Section, Settings
from ...sim.settings import LidarConfig, PathKeys
from ...sources.base import FrameSource
from ..base import SMOOTHED_ATE_GUARD, GuardedMetric, SuiteFile, first_line
from ..capabilities import EnvSlots, SceneMarks
from ..plane import LidarTrack
from .settings import PostDetectorConfig

# the sources a cached sequence depends on: shared simulation and belief, measurement models, this track
CODE = ("sim", "models", "belief", "tracks/planar")
DEFAULT_FRAMES = 40
SUITES = {"planar": False, "planar_ci": True, "planar_isam2_ci": True}
GTSAM = "gtsam is not installed (pip install 'assocbench[gtsam]'; from a clone: pip install '.[gtsam]')"
# the open-loop belief of a robot in the plane has no pixels and no viewing angle; the estimator
# section's camera parts (RGB-D depth, pixel noise, the landmark initialiser) do not apply
BELIEF = Section(BeliefConfig, exclude=("sigma_pixel", "max_view_angle"))
ESTIMATOR = Section(EstimatorConfig, exclude=("init", "depth_sigma", "depth_sigma_quadratic", "pixel_noise"))


class PlanarTrack(LidarTrack):
    """Scenes whose landmarks are ``lm*`` cylinder geoms (posts)."""

    name = "planar"
    summary = "a 2-D lidar among identical posts, circle fits, range-bearing; EKF-SLAM or GTSAM iSAM2"
    estimator_words = "planar EKF-SLAM or iSAM2, the difficulty's suffix"
    code = CODE
    maker = "assocbench.tracks.planar.sequence:make_planar_sequence"

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((PathKeys,), {"lidar": Section(LidarConfig), "posts": Section(PostDetectorConfig),
                                    "belief": BELIEF, "estimator": ESTIMATOR})

    def source(self, settings: Settings) -> FrameSource:
        """Lidar scans along the path and the posts detected in them; the iSAM2 back end's package
        is looked for first."""
        from .sequence import PlanarSequenceSpec

        if settings.estimator.name == "isam2" and settings.loop and importlib.util.find_spec("gtsam") is None:
            raise UserError(f"estimator.name: isam2 needs the gtsam package: {GTSAM}")
        spec = PlanarSequenceSpec(scene=settings.scene or next(iter(self.scenes())), trajectory=settings.trajectory,
                                  trajectory_params=dict(settings.trajectory_params),
                                  frames=settings.frames or DEFAULT_FRAMES, seed=settings.seed,
                                  lidar=settings.lidar, posts=settings.posts)
        spec.check()
        return self.lidar_source(spec)

    def problem(self, source: FrameSource, k: int, run: Any):
        from ..plane_belief import make_planar_problem

        return make_planar_problem(source.sequence, k, run.belief, run.seed)

    def guards(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """Accuracy, and closed loop the filtered and (where the baseline has it) smoothed ATE."""
        return super().guards(loop) + ((SMOOTHED_ATE_GUARD,) if loop else ())

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        from ...sim.scenegen.planar import PLANAR_SCENES

        return {name: first_line(build.__doc__) for name, build in PLANAR_SCENES.items()}

    # --- capabilities ----------------------------------------------------------------------
    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.landmark_geoms > 0

    def estimator(self, source: FrameSource, run: Any):
        from ..plane_estimator import make_planar_estimator

        return make_planar_estimator(source.sequence, run.estimator, run.belief, run.seed)

    def loop_sensor(self, source: FrameSource, run: Any):
        from ..plane_sensor import PlanarSensor

        return PlanarSensor(source.sequence, run.belief, run.estimator, run.seed)

    def env_slots(self, run: Any) -> EnvSlots:
        """N: every post; M: the most posts a scan can yield (geometric: one per post; lidar: one
            per ``posts.min_points`` beams) plus ``belief.clutter``."""
        from ...sim.planar_scene import load_planar_scene

        spec = run.source.spec
        posts = len(load_planar_scene(spec.scene).posts)
        detections = posts if spec.lidar.mode == "geometric" else spec.lidar.beams // spec.posts.min_points
        return EnvSlots(posts, detections + run.belief.clutter)

    def map_figure(self, frames: Any, scene: str, title: str):
        """The shared top view: true path, odometry, estimates and final maps over the posts."""
        from ...sim.planar_scene import load_planar_scene
        from ...viz.loop_plots import landmark_map_figure

        return landmark_map_figure(frames, load_planar_scene(scene).posts, title)

    def picture_map(self, seq: Any) -> dict[str, np.ndarray]:
        return {"posts": seq.posts}

    def feature_shapes(self, seq: Any, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """Each detection ``(r, φ)`` at ``r (cos φ, sin φ)``."""
        z = np.asarray(z, float).reshape(-1, 2)
        return {"points": z[:, :1] * np.column_stack([np.cos(z[:, 1]), np.sin(z[:, 1])])}

    def unseen(self, seq: Any, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        return {"unseen_posts": seq.posts[landmarks]}

    def estimated_map(self, estimator: Any) -> tuple[np.ndarray, np.ndarray]:
        """The filter's posts and which are confirmed."""
        xy = np.asarray(estimator.landmarks, float).reshape(-1, 2)
        return xy, np.asarray(estimator.book.confirmed, bool).reshape(len(xy))
