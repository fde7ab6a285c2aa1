"""The camera track: rendered RGB frames, Shi-Tomasi corners, the pinhole bundle (lab 8). Light to
import: rendering, detection and the estimator load inside the hooks."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...belief.config import BeliefConfig
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...settings import Schema, Section, Settings
from ...sim.settings import ImageKeys, PathKeys
from ...sources.base import FrameSource
from ..base import FeatureTrack, SuiteFile, first_line
from ..capabilities import EnvSlots, GymEnv, SceneMarks, gym_envs_of
from .settings import DetectorConfig, TruthConfig

DEFAULT_FRAMES = 40
SUITES = {"leaderboard": False, "ci": True, "loop": False, "loop_ci": True}   # name -> guarded by check
SCENES = ("room", "checkerboard", "corridor")


class CameraTrack(FeatureTrack):
    """Rendered frames of scenes whose landmarks are ``lm*`` sites; every MJCF no other track claims."""

    name = "camera"
    summary = "rendered RGB frames, Shi-Tomasi corners, pinhole model; camera EKF-SLAM in the closed loop"
    estimator_words = "camera EKF-SLAM"
    renders_frames = True    # sequences are MuJoCo GL images: the envs' render_mode draws them, no fork after
    fallback = True          # an MJCF that follows no track's convention is a camera scene

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((PathKeys, ImageKeys), {"detector": Section(DetectorConfig), "truth": Section(TruthConfig),
                                              "belief": Section(BeliefConfig), "estimator": Section(EstimatorConfig)})

    def source(self, settings: Settings) -> FrameSource:
        """Rendered frames and detected corners along the path; RGB-D depth at each feature for
        slam."""
        from ...sim.trajectory import check_trajectory_params
        from .sequence import SequenceSpec, camera_source

        est = settings.estimator
        if est.name != "ekf":
            raise UserError(f"estimator.name {est.name} is not the camera track's: its estimator is ekf")
        res = settings.resolution
        spec = SequenceSpec(
            scene=settings.scene or SCENES[0], trajectory=settings.trajectory, frames=settings.frames or DEFAULT_FRAMES,
            seed=settings.seed, width=res[0], height=res[1], msaa=settings.msaa,
            trajectory_params=dict(settings.trajectory_params), detector=settings.detector, truth=settings.truth,
            feature_depth=settings.loop and est.mode == "slam",   # RGB-D, and the truth of texture corners
        )
        check_trajectory_params(spec.resolved_trajectory(), spec.trajectory_params)
        return camera_source(spec)

    def problem(self, source: FrameSource, k: int, run: Any):
        from .belief import make_problem

        return make_problem(source.sequence, k, run.belief, run.seed)

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        from ...sim.scenegen.camera import SCENES as BUILDERS

        return {name: first_line(build.__doc__) for name, build in BUILDERS.items()}

    # --- capabilities ----------------------------------------------------------------------
    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.landmark_sites > 0

    def estimator(self, source: FrameSource, run: Any):
        from .estimator import make_camera_estimator

        return make_camera_estimator(source.sequence, run.estimator, run.belief, run.seed)

    def loop_sensor(self, source: FrameSource, run: Any):
        from .loop import CameraSensor

        return CameraSensor(source.sequence, run.belief, run.estimator, run.seed)

    def frame_picture(self, run: Any, index: int) -> tuple[np.ndarray, str]:
        from .pictures import frame_picture

        return frame_picture(run, index)

    def run_pictures(self, run: Any, source: FrameSource, frames):
        from .pictures import run_pictures

        return run_pictures(run, source.sequence, frames)

    def gym_envs(self) -> tuple[GymEnv, ...]:
        return gym_envs_of(self.scenes(), ("open", "loop"))

    def env_slots(self, run: Any) -> EnvSlots:
        """N: every landmark of the scene; M: the detector's ``max_features`` plus ``belief.clutter``."""
        from ...sim.scene import load_scene

        spec = run.source.spec
        return EnvSlots(len(load_scene(spec.scene).landmarks), spec.detector.max_features + run.belief.clutter)

    def trajectories(self) -> list[tuple[str, str]]:
        from ...sim.trajectory import TRAJECTORIES

        return [(name, first_line(fn.__doc__)) for name, fn in TRAJECTORIES.items()]

    def map_figure(self, frames: Any, scene: str, title: str):
        """The shared top view: true path, estimates and final maps over the true landmarks."""
        from ...sim.scene import load_scene
        from ...viz.loop_plots import landmark_map_figure

        return landmark_map_figure(frames, load_scene(scene).landmarks, title)
