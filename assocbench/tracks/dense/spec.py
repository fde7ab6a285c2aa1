"""A dense run's settings: sections ``depth``, ``icp``, ``fusion`` and ``dense`` of a run config.

The method implies the track: ``projective`` or ``kdtree`` (``DENSE_METHODS``) runs the dense
track on the scene, which must be a camera scene (``lm*`` sites place its path). Every value is
checked here, before anything renders.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ...associators.dense.registry import DENSE_METHODS, make_dense_associator
from ...errors import UserError
from ...validation import check_number, free_mapping, typed_section
from ..base import scene_track
from .depth_sensor import DepthConfig
from .fusion import FusionConfig
from .icp import IcpConfig
from .sequence import DenseSequenceSpec

TRACKING = ("model", "frame", "truth")


@dataclass(frozen=True)
class DenseConfig:
    """Section ``dense:``: how frames are tracked and how truth is judged."""

    tracking: str = "model"     # model: frame-to-model ICP | frame: frame-to-frame | truth: fuse at true poses
    truth_tol: float = 0.03     # m: a pair is true when both lie on one geom with true positions this close
    path_frames: int = 200      # the path is laid out over this many frames; a run takes its first ones

    def check(self) -> None:
        if self.tracking not in TRACKING:
            raise UserError(f"dense.tracking must be one of {', '.join(TRACKING)}, got {self.tracking!r}")
        check_number(self.truth_tol, "dense.truth_tol", lo=0, hi=1, lo_open=True)
        check_number(self.path_frames, "dense.path_frames", integer=True, lo=2)


@dataclass(frozen=True)
class DenseRunSpec:
    """A resolved dense run."""

    sequence: DenseSequenceSpec
    method: str
    params: dict
    icp: IcpConfig = field(default_factory=IcpConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    dense: DenseConfig = field(default_factory=DenseConfig)
    seed: int = 0


def is_dense(method: object) -> bool:
    """Whether ``method`` names a dense associator (the method implies the track)."""
    return isinstance(method, str) and method in DENSE_METHODS


def dense_run_spec(cfg: dict) -> DenseRunSpec:
    """The dense run of a merged, size-checked config."""
    track = scene_track(cfg["scene"])
    if track != "camera":
        raise UserError(f"method {cfg['method']} runs the dense track, on a camera scene (room, checkerboard, "
                        f"corridor, bays, crates or a user MJCF with lm* sites); scene {cfg['scene']!r} is a "
                        f"{track} scene")
    if cfg["loop"]:
        raise UserError(f"method {cfg['method']} runs the dense track, which always tracks with its own "
                        "estimates (set dense.tracking); drop --loop / loop: true")
    dense = typed_section(DenseConfig, cfg["dense"], "dense")
    dense.check()
    most = cfg["limits"]["frames"]
    if dense.path_frames > most:
        raise UserError(f"dense.path_frames {dense.path_frames} exceeds limits.frames = {most} (the path is "
                        "computed over that many frames); lower it or raise limits.frames")
    res = cfg["resolution"]
    seq = DenseSequenceSpec(scene=cfg["scene"], trajectory=cfg["trajectory"],
                            trajectory_params=free_mapping(cfg, "trajectory_params"), frames=cfg["frames"],
                            seed=cfg["seed"], width=res[0], height=res[1],
                            depth=typed_section(DepthConfig, cfg["depth"], "depth"), path_frames=dense.path_frames)
    seq.check()
    icp = typed_section(IcpConfig, cfg["icp"], "icp")
    icp.check()
    fusion = typed_section(FusionConfig, cfg["fusion"], "fusion")
    fusion.check()
    params = free_mapping(cfg, "params")
    make_dense_associator(cfg["method"], **params)   # bad parameters are refused now
    if cfg["frames"] < 2:
        raise UserError("the dense track tracks frame 1 from frame 0: use at least 2 frames")
    return DenseRunSpec(seq, cfg["method"], params, icp, fusion, dense, cfg["seed"])
