"""``AssociationEnv``'s constructor arguments, checked up front: a bad one is a one-line
``UserError`` in the parent process (``make_vec``), never a broken worker at the first ``reset``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import UserError
from ..harness.config import RunSpec, defaults, merge, run_spec
from ..harness.suite import shipped_difficulties
from ..sim.settings import MAX_SIDE, MIN_SIDE
from ..tracks.base import Track
from ..tracks.capabilities import GymEnvs, OwnFrames, has, lacks
from ..tracks.inference import infer_track
from ..tracks.registry import get_track
from ..validation import check_number


def _plain(value: Any) -> Any:
    """NumPy scalars as Python numbers, so ``frames=np.int64(5)`` is accepted like ``5``."""
    return value.item() if isinstance(value, (np.integer, np.floating)) else value


def _resolution(resolution: Any) -> list[int]:
    if isinstance(resolution, (str, bytes)) or not hasattr(resolution, "__len__") or len(resolution) != 2:
        raise UserError(f"resolution must be (width, height) in pixels, got {resolution!r}")
    for name, value in zip(("width", "height"), resolution):
        check_number(_plain(value), f"resolution {name}", integer=True, lo=MIN_SIDE, hi=MAX_SIDE)
    return [int(v) for v in resolution]


def _difficulty(difficulty: Any) -> dict:
    """The run-config override of a difficulty: a shipped level, or belief settings."""
    levels = shipped_difficulties()
    if isinstance(difficulty, str):
        if difficulty not in levels:
            raise UserError(f"unknown difficulty {difficulty!r}: choose one of {', '.join(levels)} or pass a mapping")
        return levels[difficulty]
    if not isinstance(difficulty, Mapping):
        raise UserError(f"difficulty must be one of {', '.join(levels)} or a mapping of belief settings, "
                        f"got {difficulty!r}")
    belief = {}
    for key, value in difficulty.items():
        belief[key] = check_number(_plain(value), f"difficulty.{key}")
    return {"belief": belief}


def env_config(scene: Any, trajectory: Any, frames: Any, difficulty: Any, resolution: Any,
               config: Any, track: Any = None) -> tuple[dict, RunSpec]:
    """The env's merged run config and ``RunSpec`` (every value checked); a bad argument is a
    one-line ``UserError`` naming it. The track is ``track`` (or ``config["track"]``), else the
    scene's; ``trajectory`` and ``resolution`` apply where the track has them."""
    if not isinstance(scene, (str, os.PathLike)) or not str(scene):
        raise UserError(f"scene must be a scene's name or the path of a file of the track's kind, got {scene!r}")
    if trajectory is not None and not isinstance(trajectory, str):
        raise UserError(f"trajectory must be a trajectory name or None, got {trajectory!r}")
    frames = check_number(_plain(frames), "frames", integer=True, lo=1)
    if config is not None and not isinstance(config, Mapping):
        raise UserError(f"config must be a mapping of run-config overrides, got {config!r}")
    named = track if track is not None else (config or {}).get("track")
    impl = get_track(named) if named is not None else infer_track(os.fspath(scene), None)
    cfg = defaults(impl)
    if "belief" in cfg:   # a difficulty is belief settings: the shipped levels' (medium by default)
        cfg = merge(cfg, _difficulty("medium" if difficulty is None else difficulty), "difficulty", impl.name)
    elif difficulty is not None:
        raise UserError(f"difficulty sets the open-loop belief, which the {impl.name} track has not: drop it "
                        "(or set the track's own settings with config=)")
    cfg = merge(cfg, {k: v for k, v in dict(config or {}).items() if k != "track"}, "config", impl.name)
    given = {"scene": os.fspath(scene), "frames": frames}
    if trajectory is not None or "trajectory" in cfg:
        given["trajectory"] = trajectory
    if "resolution" in cfg:
        given["resolution"] = _resolution(resolution)
    cfg = merge(cfg, given, "env arguments", impl.name)
    return cfg, run_spec(cfg)


def env_track(spec: RunSpec) -> Track:
    """The run's track if it offers this kind of env (open or closed loop), else a one-line
    ``UserError`` saying why."""
    track = spec.track_impl
    where = f"scene {spec.source.name!r}"
    if not has(track, GymEnvs) or has(track, OwnFrames):
        raise lacks(track, f"Gymnasium env ({where})", "its frames are not association problems with a pairing to "
                    "choose; run it with `assocbench run`")
    kinds = {env.loop for env in track.gym_envs()}
    if spec.loop in kinds:
        return track
    kind = "closed-loop" if spec.loop else "open-loop"
    other = "only an open-loop one" if False in kinds else "only a closed-loop one" if kinds else "none at all"
    raise UserError(f"the {track.name} track ({where}) offers no {kind} Gymnasium env ({other})")
