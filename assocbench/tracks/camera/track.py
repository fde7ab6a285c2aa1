"""The camera track: rendered RGB frames, Shi-Tomasi corners, the pinhole bundle (lab 8)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...sim.scene import load_scene
from ...sim.scenegen.camera import SCENES
from ...sim.trajectory import TRAJECTORIES, check_trajectory_params
from ...validation import free_mapping, typed_section
from ..base import EnvSlots, SceneMarks, Track, first_line, register_track
from .belief import make_problem
from .detect import DetectorConfig
from .estimator import make_camera_estimator
from .loop import CameraSensor
from .pictures import frame_picture, run_pictures
from .sequence import CACHE_FOLDER, Sequence, SequenceSpec, load_sequence
from .truth import TruthConfig


class CameraTrack(Track):
    """Rendered frames of scenes whose landmarks are ``lm*`` sites; every scene no other track claims."""

    name = "camera"
    summary = "rendered RGB frames, Shi-Tomasi corners, pinhole model; camera EKF-SLAM in the closed loop"
    ci_suites = ("ci", "loop_ci")
    suites = ("leaderboard", "ci", "loop", "loop_ci")
    pictures = True
    renders_frames = True
    gym_modes = ("open", "loop")
    fallback = True
    spec_type = SequenceSpec

    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.landmark_sites > 0

    def section_types(self) -> dict[str, type]:
        return {"detector": DetectorConfig, "truth": TruthConfig}

    def sequence_spec(self, cfg: dict, estimator: EstimatorConfig) -> SequenceSpec:
        """Rendered frames and detected corners (``resolution``, ``msaa``, ``detector``,
        ``truth``); RGB-D depth at each feature for the closed loop's slam mode."""
        if estimator.name != "ekf":
            raise UserError(f"estimator.name {estimator.name} serves the planar track only; scene {cfg['scene']!r} "
                            "is a camera scene, whose estimator is ekf")
        res = cfg["resolution"]
        seq = SequenceSpec(
            scene=cfg["scene"], trajectory=cfg["trajectory"], frames=cfg["frames"], seed=cfg["seed"],
            width=res[0], height=res[1], msaa=cfg["msaa"], trajectory_params=free_mapping(cfg, "trajectory_params"),
            detector=typed_section(DetectorConfig, cfg["detector"], "detector"),
            truth=typed_section(TruthConfig, cfg["truth"], "truth"),
            feature_depth=cfg["loop"] and estimator.mode == "slam",   # RGB-D, and the truth of texture corners
        )
        check_trajectory_params(seq.resolved_trajectory(), seq.trajectory_params)
        return seq

    def frame_picture(self, spec, index: int) -> tuple[np.ndarray, str]:
        return frame_picture(spec, index)

    def run_pictures(self, spec, seq: Sequence, frames):
        return run_pictures(spec, seq, frames)

    def load_sequence(self, spec: SequenceSpec, cache_dir: Path | None = None, use_cache: bool = True) -> Sequence:
        return load_sequence(spec, cache_dir, use_cache)

    def cache_folder(self) -> str:
        return CACHE_FOLDER

    def problems(self, seq: Sequence, belief, seed: int) -> list:
        return [make_problem(seq, k, belief, seed) for k in range(len(seq))]

    def make_estimator(self, seq: Sequence, cfg: EstimatorConfig, belief, seed: int):
        return make_camera_estimator(seq, cfg, belief, seed)

    def loop_sensor(self, seq: Sequence, belief, est: EstimatorConfig, seed: int) -> CameraSensor:
        return CameraSensor(seq, belief, est, seed)

    def env_slots(self, spec) -> EnvSlots:
        """N: every landmark of the scene; M: the detector's ``max_features`` plus ``belief.clutter``."""
        return EnvSlots(len(load_scene(spec.sequence.scene).landmarks),
                        spec.sequence.detector.max_features + spec.belief.clutter)

    def shipped_scenes(self) -> dict[str, str]:
        return {name: first_line(build.__doc__) for name, build in SCENES.items()}

    def trajectories(self) -> list[tuple[str, str]]:
        return [(name, first_line(fn.__doc__)) for name, fn in TRAJECTORIES.items()]

    def landmarks(self, scene: str) -> np.ndarray:
        return load_scene(scene).landmarks


register_track(CameraTrack)
