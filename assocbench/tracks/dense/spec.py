"""A dense run's settings: sections ``depth``, ``icp``, ``fusion`` and ``dense`` of a run config.

A dense method (``projective``, ``kdtree`` or a user's ``DenseAssociator``) implies the track;
the scene must follow the camera convention (``lm*`` sites place its path). Every value is
checked here, before anything renders.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import UserError
from ...validation import check_number, free_mapping, typed_section
from ..base import scene_track
from .depth_sensor import DepthConfig
from .fusion import FusionConfig
from .icp import IcpConfig
from .sequence import DenseSequenceSpec

TRACKING = ("model", "frame", "truth")
PREDICTION = ("view", "map")


@dataclass(frozen=True)
class DenseConfig:
    """Section ``dense:``: how frames are tracked and how truth is judged.

    tracking: what ICP registers each frame to: model (the fused map, the homework's frame-to-model),
        frame (the previous frame's points, frame-to-frame) or truth (the map fused at the true
        poses, ICP from the previous true pose: one step's error without drift).
    prediction: the map as ICP's source when tracking the model or the truth, either view (the map
        rendered into the predicted view, one point a pixel, KinectFusion's predicted maps, see
        ``tracks.dense.prediction``; an ICP iteration costs the pixel count) or map (every map
        point, the homework's whole-map projection; an ICP iteration costs the map's size).
    index: splat and fuse only the map's blocks whose bounding box meets the view frustum (the map's
        index, ``tracks.dense.fusion``): the same numbers bit for bit, a per-frame cost that follows
        what is in view; false visits every map point in every frame (the whole-map baseline that
        ``benchmarks/dense_rate.py`` times).
    truth_tol: a pair is true when map point and pixel lie on one geom with true positions this
        close (m).
    path_frames: the camera path is laid out over this many frames; a run takes its first ones.
    """

    tracking: str = "model"
    prediction: str = "view"
    index: bool = True
    truth_tol: float = 0.03
    path_frames: int = 200

    def check(self) -> None:
        if self.tracking not in TRACKING:
            raise UserError(f"dense.tracking must be one of {', '.join(TRACKING)}, got {self.tracking!r}")
        if self.prediction not in PREDICTION:
            raise UserError(f"dense.prediction must be one of {', '.join(PREDICTION)}, got {self.prediction!r}")
        if not isinstance(self.index, bool):
            raise UserError(f"dense.index must be true or false, got {self.index!r}")
        check_number(self.truth_tol, "dense.truth_tol", lo=0, hi=1, lo_open=True)
        check_number(self.path_frames, "dense.path_frames", integer=True, lo=2)


def dense_sequence_spec(cfg: dict) -> DenseSequenceSpec:
    """The depth sequence of a merged, size-checked config, with the track's own refusals: a
    scene of another track, ``loop``, fewer than two frames, a path longer than ``limits.frames``."""
    track = scene_track(cfg["scene"])
    if track != "camera":
        raise UserError(f"method {cfg['method']} runs the dense track, on a camera scene (room, checkerboard, "
                        f"corridor, bays, crates or a user MJCF with lm* sites); scene {cfg['scene']!r} is a "
                        f"{track} scene")
    if cfg["loop"]:
        raise UserError(f"method {cfg['method']} runs the dense track, which always tracks with its own "
                        "estimates (set dense.tracking); drop --loop / loop: true")
    if cfg["frames"] < 2:
        raise UserError("the dense track tracks frame 1 from frame 0: use at least 2 frames")
    dense = dense_config(cfg)
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
    return seq


def dense_config(cfg: dict) -> DenseConfig:
    """Section ``dense``, checked."""
    dense = typed_section(DenseConfig, cfg["dense"], "dense")
    dense.check()
    return dense


def dense_settings(cfg: dict) -> tuple:
    """The run's ``icp``, ``fusion`` and ``dense`` sections, typed and checked, as ``RunSpec.settings``."""
    icp = typed_section(IcpConfig, cfg["icp"], "icp")
    icp.check()
    fusion = typed_section(FusionConfig, cfg["fusion"], "fusion")
    fusion.check()
    return (("icp", icp), ("fusion", fusion), ("dense", dense_config(cfg)))
