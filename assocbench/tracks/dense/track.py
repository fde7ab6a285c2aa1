"""The dense track: depth frames, projective data association, point-to-plane ICP, point fusion."""

from __future__ import annotations

from dataclasses import asdict

from ...associators.dense.registry import DENSE_METHODS
from ...sim.scene import load_scene
from ...sim.scenegen.dense import DENSE_SCENES
from ..base import Track, first_line, register_track
from .depth_sensor import DepthConfig
from .fusion import FusionConfig
from .icp import IcpConfig
from .sequence import DenseSequenceSpec
from .spec import DenseConfig


class DenseTrack(Track):
    """Depth frames of camera-convention scenes; a dense method (projective, kdtree) implies it."""

    name = "dense"
    summary = "depth frames, projective data association, point-to-plane ICP, point-based fusion"
    suites = ("dense",)
    spec_type = DenseSequenceSpec

    def claims_method(self, method: str) -> bool:
        return isinstance(method, str) and method in DENSE_METHODS

    def config_sections(self) -> dict[str, dict]:
        return {"depth": asdict(DepthConfig()), "icp": asdict(IcpConfig()), "fusion": asdict(FusionConfig()),
                "dense": asdict(DenseConfig())}

    def shipped_scenes(self) -> dict[str, str]:
        return {name: first_line(build.__doc__) for name, build in DENSE_SCENES.items()}

    def landmarks(self, scene: str):
        return load_scene(scene).landmarks


register_track(DenseTrack)
