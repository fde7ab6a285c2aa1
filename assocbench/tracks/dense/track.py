"""The dense track: depth frames, dense association, point-to-plane ICP, point fusion. It runs its
own frame loop (``OwnFrames``) through the harness's ``MethodCalls``. Light to import: the pipeline
loads inside the hooks."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...settings import Schema, Section, Settings
from ...sim.settings import ImageKeys, PathKeys
from ...sources.base import FrameSource
from ..base import Columns, GuardedMetric, Metric, SuiteFile, Track, first_line
from ..capabilities import MethodCalls
from .columns import DENSE_COLUMNS, FRAME_COLUMNS
from .settings import DenseConfig, DepthConfig, FusionConfig, IcpConfig

SUITES = {"dense": False, "dense_ci": True}


def gate_params(run: Any) -> dict:
    """The method's parameters with the run's depth noise for a gate that grows with it, unless the
    user set them."""
    from ...associators.registry import associator_class

    fields = getattr(associator_class(run.method), "__dataclass_fields__", {})
    depth = run.settings.depth
    noise = {k: getattr(depth, k) for k in ("sigma_base", "sigma_quad") if k in fields}
    return noise | dict(run.params)


class DenseTrack(Track):
    """Depth frames of scenes whose ``lm*`` sites place the camera's path; a dense method
    (projective, kdtree, or a user's ``DenseAssociator``) implies it."""

    name = "dense"
    summary = "depth frames, projective data association, point-to-plane ICP, point-based fusion"
    # per-frame pictures would need the depth frames rendered again and ICP's correspondences kept
    pictures_elsewhere = ("map.png (the fused map from above, coloured by its distance to the true surface) and "
                          "map.ply, which `assocbench run --out DIR` writes for a dense method; frame and render "
                          "draw the same scene's camera frames with a feature method (e.g. --method jcbb)")

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((PathKeys, ImageKeys), {"depth": Section(DepthConfig), "icp": Section(IcpConfig),
                                              "fusion": Section(FusionConfig), "dense": Section(DenseConfig)})

    def source(self, settings: Settings) -> FrameSource:
        from .spec import dense_source_of

        return dense_source_of(settings)

    def columns(self, loop: bool) -> Columns:
        return Columns(DENSE_COLUMNS, Metric("ate_mm", False, "mm"), FRAME_COLUMNS)

    def guards(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """Correspondence precision and recall may fall by the suite's ``tolerance``; ATE and the
        map's median error (mm) may rise by its ``ate_tolerance`` (m)."""
        return (GuardedMetric("precision", True, hi=1.0), GuardedMetric("recall", True, hi=1.0),
                GuardedMetric("ate_mm", False, "ate_tolerance", 1000.0),
                GuardedMetric("map_median_mm", False, "ate_tolerance", 1000.0))

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        from ...sim.scenegen.dense import DENSE_SCENES

        return {name: first_line(build.__doc__) for name, build in DENSE_SCENES.items()}

    # --- capabilities: its own frame loop, methods, leaderboard and files ---------------------
    def records(self, source: FrameSource, run: Any, calls: MethodCalls, first: int = 0,
                artifacts: Path | None = None):
        from ...associators.registry import make_dense_associator
        from .run import dense_records

        return dense_records(source.sequence, run, calls, lambda: make_dense_associator(run.method, **gate_params(run)),
                             first, artifacts)

    def summarize(self, frames: Any) -> dict:
        from .summary import summarize_dense

        return summarize_dense(frames)

    def check_method(self, method: str, params: dict) -> None:
        from ...associators.registry import make_dense_associator

        make_dense_associator(method, **params)   # bad names and parameters are refused now

    def describe(self, run: Any) -> tuple[dict, str]:
        tracking = run.settings.dense.tracking
        return {"tracking": tracking}, f"{tracking} tracking"

    def claims_method(self, method: str) -> bool:
        from ...associators.registry import is_dense

        return isinstance(method, str) and is_dense(method)

    def warm_up(self) -> None:
        from .warm import warm_dense

        warm_dense()

    def run_files(self, frames: Any, artifacts: Path, out: Path, title: str) -> dict:
        """``map.ply`` (the fused map with its weight and distance to the true surface, mm) and
        ``map.png`` (its top view, coloured by that distance)."""
        from .plots import map_writers

        fused = artifacts / "map.npz"   # absent when the run could not start (no map was fused)
        return map_writers(frames, fused, out, title) if fused.is_file() else {}

    def leaderboard_table(self, summaries: Any) -> Any:
        from .leaderboard import dense_table

        return dense_table(summaries)

    def write_leaderboard(self, summaries: Any, frames: Any, out: Path) -> dict:
        from .leaderboard import write_dense_leaderboard

        return write_dense_leaderboard(summaries, frames, out)
