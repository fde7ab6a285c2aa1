"""The dense track: depth frames, projective data association, point-to-plane ICP, point fusion."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ...associators.registry import associator_class, is_dense, make_dense_associator
from ...errors import UserError
from ...sim.scene import load_scene
from ...sim.scenegen.dense import DENSE_SCENES
from ..base import GuardedMetric, MethodCalls, Track, first_line, register_track
from .depth_sensor import DepthConfig
from .fusion import FusionConfig
from .icp import IcpConfig
from .leaderboard import dense_table, write_dense_leaderboard
from .plots import map_writers
from .run import dense_records
from .sequence import CACHE_FOLDER, DenseSequence, DenseSequenceSpec, load_dense_sequence
from .spec import DenseConfig, dense_sequence_spec, dense_settings
from .summary import DENSE_COLUMNS, summarize_dense
from .warm import warm_dense


def gate_params(spec) -> dict:
    """The method's parameters, with the run's depth noise (``depth.sigma_base``, ``sigma_quad``) for
    an associator whose gate grows with it (``DenseAssociator.gate``) unless the user set them."""
    fields = getattr(associator_class(spec.method), "__dataclass_fields__", {})
    depth = spec.sequence.depth
    noise = {k: getattr(depth, k) for k in ("sigma_base", "sigma_quad") if k in fields}
    return noise | dict(spec.params)


class DenseTrack(Track):
    """Depth frames of camera-convention scenes; a dense method (projective, kdtree, or a user's
    ``DenseAssociator``) implies it."""

    name = "dense"
    summary = "depth frames, projective data association, point-to-plane ICP, point-based fusion"
    suites = ("dense", "dense_ci")
    ci_suites = ("dense_ci",)
    spec_type = DenseSequenceSpec
    has_problems = False
    # per-frame pictures would need the depth frames rendered again and ICP's correspondences kept
    pictures_elsewhere = ("map.png (the fused map from above, coloured by its distance to the true surface) and "
                          "map.ply, which `assocbench run --out DIR` writes for a dense method; frame and render "
                          "draw the same scene's camera frames with a feature method (e.g. --method jcbb)")

    def claims_method(self, method: str) -> bool:
        return isinstance(method, str) and is_dense(method)

    def section_types(self) -> dict[str, type]:
        return {"depth": DepthConfig, "icp": IcpConfig, "fusion": FusionConfig, "dense": DenseConfig}

    def sequence_spec(self, cfg: dict, estimator) -> DenseSequenceSpec:
        return dense_sequence_spec(cfg)

    def run_settings(self, cfg: dict) -> tuple:
        return dense_settings(cfg)

    def check_method(self, method: str, params: dict, loop: bool) -> None:
        make_dense_associator(method, **params)   # bad parameters are refused now

    def load_sequence(self, spec: DenseSequenceSpec, cache_dir: Path | None = None,
                      use_cache: bool = True) -> DenseSequence:
        return load_dense_sequence(spec, cache_dir, use_cache)

    def cache_folder(self) -> str:
        return CACHE_FOLDER

    def problems(self, seq, belief, seed: int) -> list:
        raise UserError("the dense track's frames are depth images, not association problems: run a dense "
                        "method (projective, kdtree) with `assocbench run`")

    def frame_records(self, seq: DenseSequence, spec, calls: MethodCalls, first: int = 0,
                      artifacts: Path | None = None):
        return dense_records(seq, spec, calls, lambda: make_dense_associator(spec.method, **gate_params(spec)),
                             first, artifacts)

    def summarize(self, frames: pd.DataFrame) -> dict:
        return summarize_dense(frames)

    def summary_columns(self, loop: bool) -> tuple[str, ...]:
        return DENSE_COLUMNS

    def warm_up(self) -> None:
        warm_dense()

    def run_labels(self, spec) -> dict:
        return {"tracking": spec.setting("dense").tracking}

    def describe_run(self, spec) -> str:
        return f"{spec.setting('dense').tracking} tracking"

    def run_writers(self, frames: pd.DataFrame, artifacts: Path, out: Path, title: str) -> dict:
        """``map.ply`` (the fused map with its weight and distance to the true surface, mm) and
        ``map.png`` (its top view, coloured by that distance)."""
        fused = artifacts / "map.npz"   # absent when the run could not start (no map was fused)
        return map_writers(frames, fused, out, title) if fused.is_file() else {}

    def check_metrics(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """Correspondence precision and recall may fall by the suite's ``tolerance``; ATE and the
        map's median error (mm) may rise by its ``ate_tolerance`` (m)."""
        return (GuardedMetric("precision", True, hi=1.0), GuardedMetric("recall", True, hi=1.0),
                GuardedMetric("ate_mm", False, "ate_tolerance", 1000.0),
                GuardedMetric("map_median_mm", False, "ate_tolerance", 1000.0))

    def leaderboard_table(self, summaries: pd.DataFrame) -> pd.DataFrame:
        return dense_table(summaries)

    def write_leaderboard(self, summaries: pd.DataFrame, frames: pd.DataFrame, out: Path) -> dict:
        return write_dense_leaderboard(summaries, frames, out)

    def shipped_scenes(self) -> dict[str, str]:
        return {name: first_line(build.__doc__) for name, build in DENSE_SCENES.items()}

    def landmarks(self, scene: str):
        return load_scene(scene).landmarks


register_track(DenseTrack)
