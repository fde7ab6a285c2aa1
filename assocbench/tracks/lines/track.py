"""The lines track: walls extracted from lidar scans as lines (α, r) with covariance. Light to
import: simulation, kernels and estimator load inside the hooks."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...belief.config import BeliefConfig
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...settings import Schema, Section, Settings
from ...sim.settings import LidarConfig, PathKeys
from ...sources.base import FrameSource
from ..base import LOOP_FRAME_COLUMNS, Columns, SuiteFile, first_line
from ..capabilities import EnvSlots, SceneMarks
from ..plane import LidarTrack
from .settings import LineExtractorConfig

# the sources a cached sequence depends on: shared simulation and belief, measurement models, this track
CODE = ("sim", "models", "belief", "tracks/lines")
CLUTTER_PIECE_M = 1.0   # how long the top view draws a clutter line, which has no extent
DEFAULT_FRAMES = 40
SUITES = {"lines": False, "lines_ci": True}
BELIEF = Section(BeliefConfig, exclude=("sigma_pixel", "max_view_angle"))
# localisation on a known map: none of the settings that make, confirm or drop landmarks apply
ESTIMATOR = Section(EstimatorConfig, exclude=("init", "depth_sigma", "depth_sigma_quadratic", "pixel_noise",
                                              "target_paired", "max_new_per_frame", "max_landmarks",
                                              "drop_after", "new_landmark_gate"))


class LinesTrack(LidarTrack):
    """Scenes whose map is ``lw*`` wall geoms (and no ``lm*`` landmarks)."""

    name = "lines"
    summary = "walls from 2-D lidar scans as lines (α, r) with Σ; EKF localisation on the known map"
    estimator_words = "EKF localisation on the known map of walls, the suffix is the line extraction method"
    code = CODE
    maker = "assocbench.tracks.lines.sequence:make_line_sequence"

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((PathKeys,), {"lidar": Section(LidarConfig), "lines": Section(LineExtractorConfig),
                                    "belief": BELIEF, "estimator": ESTIMATOR})

    def source(self, settings: Settings) -> FrameSource:
        """Lidar scans along the scene's path and the wall lines extracted from them (``lidar``,
        ``lines``); its estimator is the EKF localisation on the known map."""
        from .sequence import LineSequenceSpec

        est = settings.estimator
        if est.name != "ekf" or est.mode != "localisation":
            raise UserError(f"the lines track's estimator is the EKF localisation on the known map: set "
                            f"estimator.name: ekf and estimator.mode: localisation (got {est.name}, {est.mode})")
        if settings.lidar.mode != "lidar":
            raise UserError(f"lidar.mode {settings.lidar.mode} serves the planar track's posts; lines are extracted "
                            "from ray-cast scans: set lidar.mode: lidar")
        spec = LineSequenceSpec(scene=settings.scene or next(iter(self.scenes())), trajectory=settings.trajectory,
                                trajectory_params=dict(settings.trajectory_params),
                                frames=settings.frames or DEFAULT_FRAMES, seed=settings.seed,
                                lidar=settings.lidar, lines=settings.lines)
        spec.check()
        return self.lidar_source(spec)

    def problem(self, source: FrameSource, k: int, run: Any):
        from .belief import make_line_problem

        return make_line_problem(source.sequence, k, run.belief, run.seed)

    def columns(self, loop: bool) -> Columns:
        """The shared columns; a closed loop's leaderboard also keeps the last frame's scan (its map view)."""
        cols = super().columns(loop)
        return Columns(cols.summary, cols.primary, LOOP_FRAME_COLUMNS + ("final_scan",)) if loop else cols

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        from ...sim.scenegen.lines import LINE_SCENES

        return {name: first_line(build.__doc__) for name, build in LINE_SCENES.items()}

    # --- capabilities ----------------------------------------------------------------------
    def claims_scene(self, marks: SceneMarks) -> bool:
        return marks.wall_geoms > 0

    def estimator(self, source: FrameSource, run: Any):
        from .estimator import make_line_estimator

        return make_line_estimator(source.sequence, run.estimator, run.belief, run.seed)

    def loop_sensor(self, source: FrameSource, run: Any):
        from .loop import LinesSensor

        return LinesSensor(source.sequence, run.belief, run.estimator, run.seed)

    def warm_up(self) -> None:
        from .sequence import warm_extraction

        warm_extraction()

    def env_slots(self, run: Any) -> EnvSlots:
        """N: every map line; M: the most lines a scan can yield (one per ``lines.min_points``
            beams; RANSAC stops at ``lines.max_lines``) plus ``belief.clutter``."""
        from ...sim.line_scene import load_line_scene

        spec = run.source.spec
        lines = spec.lidar.beams // spec.lines.min_points
        if spec.lines.method == "ransac":
            lines = min(lines, spec.lines.max_lines)
        return EnvSlots(len(load_line_scene(spec.scene).lines), lines + run.belief.clutter)

    def map_figure(self, frames: Any, scene: str, title: str):
        """Walls, not points: the map's faces and each method's last scan."""
        from ...sim.line_scene import load_line_scene
        from .plots import line_map_figure, snapshots

        return line_map_figure(frames, load_line_scene(scene).segments, snapshots(frames), title=title)

    def picture_map(self, seq: Any) -> dict[str, np.ndarray]:
        return {"walls": seq.segments}

    def feature_shapes(self, seq: Any, k: int, z: np.ndarray) -> dict[str, np.ndarray]:
        """The extracted segments; a clutter line has none, so a ``CLUTTER_PIECE_M`` piece at its
        foot point ``r (cos α, sin α)``."""
        ends = np.asarray(seq.endpoints[k], float).reshape(-1, 2, 2)
        clutter = np.asarray(z, float).reshape(-1, 2)[len(ends):]
        foot = clutter[:, 1:] * np.column_stack([np.cos(clutter[:, 0]), np.sin(clutter[:, 0])])
        along = CLUTTER_PIECE_M / 2 * np.column_stack([-np.sin(clutter[:, 0]), np.cos(clutter[:, 0])])
        return {"segments": np.concatenate([ends, np.stack([foot - along, foot + along], axis=1)])}

    def unseen(self, seq: Any, landmarks: np.ndarray) -> dict[str, np.ndarray]:
        return {"unseen_walls": seq.segments[np.isin(seq.segment_line, landmarks)]}

    def picture_note(self) -> str:
        return f"a clutter line (alpha, r) is drawn as a {CLUTTER_PIECE_M:g} m piece at its foot point"
