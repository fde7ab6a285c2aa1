"""The recorded range-bearing track: a log of odometry and sightings (Victoria Park from the gtsam
wheel, or your own: ``sources.range_bearing_log``), scored against its reference association and
GTSAM's reference solution. Light to import."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path
from typing import Any

from ...belief.config import BeliefConfig
from ...errors import UserError
from ...estimators.config import EstimatorConfig
from ...settings import Schema, Section, Settings
from ..base import SMOOTHED_ATE_GUARD, Columns, FeatureTrack, GuardedMetric, SuiteFile
from .settings import LogConfig

VICTORIA_PARK = "victoria_park"
SUITES = {"real_victoria": False, "real_victoria_open": False, "real_victoria_ci": True}
GTSAM = "gtsam is not installed (pip install 'assocbench[gtsam]'; from a clone: pip install '.[gtsam]')"
# a recorded sensor's noise is the log's: no pixel noise, no viewing angle; the odometry's noise is
# the log's too (its scale is log.odometry_scale), and no camera part of the estimator applies
BELIEF = Section(BeliefConfig, exclude=("sigma_pixel", "max_view_angle"))
ESTIMATOR = Section(EstimatorConfig, exclude=("odometry_sigma_translation", "odometry_sigma_rotation",
                                              "odometry_miscalibration", "init", "depth_sigma",
                                              "depth_sigma_quadratic", "pixel_noise"))
OWN_COLUMNS = ("pair_precision", "pair_recall", "reference_landmarks")


def shipped_log(name: str) -> Path | None:
    """The path of a dataset shipped in the gtsam wheel (``victoria_park``), found without importing
    gtsam; None where gtsam is not installed."""
    spec = importlib.util.find_spec("gtsam")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations))) / "Data" / f"{name}.txt"


class PlanarLogTrack(FeatureTrack):
    """A recorded range-bearing log: odometry and landmark sightings with a reference association."""

    name = "planar_log"
    summary = ("a recorded range-bearing log (Victoria Park, or yours), scored against its reference association; "
               "EKF-SLAM or GTSAM iSAM2")
    estimator_words = "planar EKF-SLAM or iSAM2 on the log's odometry, the difficulty's suffix"
    pictures_elsewhere = "the leaderboard's top views (`assocbench leaderboard --suite real_victoria`)"

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((), {"log": Section(LogConfig), "belief": BELIEF, "estimator": ESTIMATOR})

    def source(self, settings: Settings):
        """The log ``scene`` names (a shipped dataset or a file) as a frame source; nothing is read
        but the file's digest until a frame is asked for."""
        from .source import PlanarLogSource

        scene = settings.scene or VICTORIA_PARK
        path = shipped_log(scene) if scene in self.scenes() else Path(scene)
        if path is None or not path.is_file():
            raise UserError(f"planar_log scene {scene!r} is neither a shipped dataset ({', '.join(self.scenes())}) nor "
                            "a log file: give one (docs/tracks/planar_log.md describes the format)")
        shipped = scene in self.scenes()
        return PlanarLogSource(path, settings.frames, settings.log.for_scene(scene if shipped else ""),
                               name=scene if shipped else None)

    def problem(self, source, k: int, run: Any):
        """Open loop: the reference solution plus errors drawn from the belief's covariance predicts
        the reference landmarks in the sensor's range (``plane_belief``)."""
        from ..plane_belief import make_planar_problem

        return make_planar_problem(source.sequence, k, run.belief, run.seed)

    def columns(self, loop: bool) -> Columns:
        """The shared columns against the reference; the closed loop adds the pairwise "same
        landmark" scores and the reference landmarks sighted."""
        cols = super().columns(loop)
        if loop:
            cols = replace(cols, summary=cols.summary + OWN_COLUMNS)
        return replace(cols, scored_against="reference")

    def guards(self, loop: bool) -> tuple[GuardedMetric, ...]:
        return super().guards(loop) + ((SMOOTHED_ATE_GUARD,) if loop else ())

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        return {VICTORIA_PARK: "Victoria Park, Sydney: a car's odometry and 3 640 lidar sightings of 151 tree trunks "
                               "over 6 969 poses (4 km), the ids the dataset's reference (shipped in the gtsam wheel)"}

    # --- capabilities ----------------------------------------------------------------------
    def unavailable(self) -> str | None:
        """The reference solution is GTSAM's, and Victoria Park ships in its wheel."""
        return GTSAM if importlib.util.find_spec("gtsam") is None else None

    def estimator(self, source, run: Any):
        from ..plane_estimator import make_planar_estimator, planar_estimator_class
        from .loop import logged

        cls = logged(planar_estimator_class(run.estimator.name))
        return make_planar_estimator(source.sequence, run.estimator, run.belief, run.seed, cls)

    def loop_sensor(self, source, run: Any):
        from .loop import LogSensor

        return LogSensor(source.sequence, run.belief, run.estimator, run.seed)

    def run_scores(self, frames: Any) -> dict:
        from .loop import run_scores

        return run_scores(frames) if "nees" in frames else {}

    def map_figure(self, frames: Any, scene: str, title: str):
        """Every method's run over the reference map and path (the log ``scene``'s)."""
        from ...sources.base import file_digest
        from ...viz.loop_plots import landmark_map_figure
        from .reference import reference_solution
        from .source import parsed_log

        path = shipped_log(scene) if scene in self.scenes() else Path(scene)
        reference = reference_solution(parsed_log(path, file_digest(path)))
        return landmark_map_figure(frames, reference.landmarks, title, scored_against="reference")
