"""A dense run's frame source from its checked settings (sections ``depth``, ``icp``, ``fusion`` and
``dense``, ``settings``), with the track's own refusals, before anything renders."""

from __future__ import annotations

from ...errors import UserError
from ...settings import Settings
from ...sim.scene import mjcf_names, resolve_scene_path
from ...sources.base import SimulatedSource
from .sequence import DEFAULT_FRAMES, DenseSequenceSpec, dense_source


def dense_source_of(settings: Settings) -> SimulatedSource:
    """The depth sequence of a run: its scene must place a camera path by ``lm*`` sites, the run
    takes at least two frames, and the path is no longer than ``limits.frames``."""
    scene = settings.scene or "bays"
    sites, _, _ = mjcf_names(resolve_scene_path(scene))
    if not sites:
        raise UserError(f"method {settings.method} runs the dense track, on a scene whose lm* sites place its "
                        f"camera path (room, checkerboard, corridor, bays, crates or a user MJCF with lm* sites); "
                        f"scene {scene!r} has none")
    frames = settings.frames or DEFAULT_FRAMES
    if frames < 2:
        raise UserError("the dense track tracks frame 1 from frame 0: use at least 2 frames")
    dense, most = settings.dense, settings.limits.frames
    if dense.path_frames > most:
        raise UserError(f"dense.path_frames {dense.path_frames} exceeds limits.frames = {most} (the path is "
                        "computed over that many frames); lower it or raise limits.frames")
    res = settings.resolution
    spec = DenseSequenceSpec(scene=scene, trajectory=settings.trajectory,
                             trajectory_params=dict(settings.trajectory_params), frames=frames, seed=settings.seed,
                             width=res[0], height=res[1], depth=settings.depth, path_frames=dense.path_frames)
    spec.check()
    return dense_source(spec)
