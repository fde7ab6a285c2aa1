"""The lines track: walls extracted from lidar scans as lines (α, r) with covariance."""

from __future__ import annotations

import numpy as np

from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...sim.lidar import LidarConfig
from ...sim.line_scene import load_line_scene
from ...sim.scenegen.lines import LINE_SCENES
from ...validation import free_mapping, typed_section
from ..base import EnvSlots, SceneMarks, first_line, register_track
from ..plane import LidarTrack
from .belief import make_line_problem
from .estimator import make_line_estimator
from .extract import LineExtractorConfig
from .loop import LinesSensor
from .plots import line_map_figure, snapshots
from .sequence import LineSequence, LineSequenceSpec, make_line_sequence, warm_extraction

# the sources a cached sequence depends on: shared simulation and belief, measurement models, this track
CODE = ("sim", "models", "belief", "tracks/lines")
CLUTTER_PIECE_M = 1.0   # how long the top view draws a clutter line, which has no extent


class LinesTrack(LidarTrack):
    """Scenes whose map is ``lw*`` wall geoms (and no ``lm*`` landmarks)."""

    name = "lines"
    summary = "walls from 2-D lidar scans as lines (α, r) with Σ; EKF localisation on the known map"
    ci_suites = ("lines_ci",)
    suites = ("lines", "lines_ci")
    spec_type = LineSequenceSpec
    gym_modes = ("open", "loop")
    code = CODE

    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.wall_geoms > 0

    def section_types(self) -> dict[str, type]:
        return {"lidar": LidarConfig, "lines": LineExtractorConfig}

    def sequence_spec(self, cfg: dict, estimator: EstimatorConfig) -> LineSequenceSpec:
        """Lidar scans along the scene's path and the wall lines extracted from them (``lidar``,
        ``lines``); its estimator is the EKF localisation on the known map."""
        if estimator.name != "ekf" or estimator.mode != "localisation":
            raise UserError(f"scene {cfg['scene']!r} is a lines scene, whose estimator is the EKF localisation on "
                            f"the known map: set estimator.name: ekf and estimator.mode: localisation (got "
                            f"{estimator.name}, {estimator.mode})")
        seq = LineSequenceSpec(scene=cfg["scene"], trajectory=cfg["trajectory"],
                               trajectory_params=free_mapping(cfg, "trajectory_params"), frames=cfg["frames"],
                               seed=cfg["seed"], lidar=typed_section(LidarConfig, cfg["lidar"], "lidar"),
                               lines=typed_section(LineExtractorConfig, cfg["lines"], "lines"))
        if seq.lidar.mode != "lidar":
            raise UserError(f"lidar.mode {seq.lidar.mode} serves the planar track's posts; lines are extracted "
                            "from ray-cast scans: set lidar.mode: lidar")
        seq.check()
        return seq

    def make_sequence(self, spec):
        return make_line_sequence(spec)

    def problems(self, seq: LineSequence, belief, seed: int) -> list:
        return [make_line_problem(seq, k, belief, seed) for k in range(len(seq))]

    def make_estimator(self, seq: LineSequence, cfg: EstimatorConfig, belief, seed: int):
        return make_line_estimator(seq, cfg, belief, seed)

    def loop_sensor(self, seq: LineSequence, belief, est: EstimatorConfig, seed: int) -> LinesSensor:
        return LinesSensor(seq, belief, est, seed)

    def warm_up(self) -> None:
        warm_extraction()

    def env_slots(self, spec) -> EnvSlots:
        """N: every line of the scene's map; M: the most lines a scan can yield (one per
        ``lines.min_points`` beams, each beam in one line; RANSAC stops at ``lines.max_lines``)
        plus ``belief.clutter``."""
        seq = spec.sequence
        lines = seq.lidar.beams // seq.lines.min_points
        if seq.lines.method == "ransac":
            lines = min(lines, seq.lines.max_lines)
        return EnvSlots(len(load_line_scene(seq.scene).lines), lines + spec.belief.clutter)

    def shipped_scenes(self) -> dict[str, str]:
        return {name: first_line(build.__doc__) for name, build in LINE_SCENES.items()}

    def picture_map(self, seq: LineSequence) -> dict[str, np.ndarray]:
        return {"walls": seq.segments}

    def feature_shapes(self, seq: LineSequence, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """The extracted lines' segments; a clutter line ``(α, r)`` has none, so a piece of
        ``CLUTTER_PIECE_M`` centred on its foot point ``r (cos α, sin α)``."""
        ends = np.asarray(seq.endpoints[k], float).reshape(-1, 2, 2)
        clutter = np.asarray(z, float).reshape(-1, 2)[len(ends):]
        foot = clutter[:, 1:] * np.column_stack([np.cos(clutter[:, 0]), np.sin(clutter[:, 0])])
        along = CLUTTER_PIECE_M / 2 * np.column_stack([-np.sin(clutter[:, 0]), np.cos(clutter[:, 0])])
        return {"segments": np.concatenate([ends, np.stack([foot - along, foot + along], axis=1)])}

    def unseen(self, seq: LineSequence, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        return {"unseen_walls": seq.segments[np.isin(seq.segment_line, landmarks)]}

    def picture_note(self) -> str:
        return f"a clutter line (alpha, r) is drawn as a {CLUTTER_PIECE_M:g} m piece at its foot point"

    def map_figure(self, frames, scene: str, title: str):
        """Walls, not points: the map's faces and each method's last scan."""
        return line_map_figure(frames, load_line_scene(scene).segments, snapshots(frames), title=title)


register_track(LinesTrack)
