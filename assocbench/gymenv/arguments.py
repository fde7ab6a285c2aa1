"""The constructor arguments of ``AssociationEnv``, checked up front: a bad one is a one-line
``UserError`` from the constructor (so ``make_vec`` refuses it in the parent process), never a
``ZeroDivisionError`` or a broken worker at the first ``reset``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import UserError
from ..harness.config import RunSpec, defaults, merge, run_spec
from ..harness.suite import shipped_difficulties
from ..sim.render import MAX_SIDE, MIN_SIDE
from ..tracks.base import Track
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
    """The run-config override a difficulty stands for: a shipped level, or belief settings."""
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
               config: Any) -> tuple[dict, RunSpec]:
    """The merged run config of an env and its resolved ``RunSpec`` (every value checked by
    ``run_spec``); a bad argument raises a one-line ``UserError`` naming it."""
    if not isinstance(scene, (str, os.PathLike)) or not str(scene):
        raise UserError(f"scene must be a shipped scene name or the path of an MJCF file, got {scene!r}")
    if trajectory is not None and not isinstance(trajectory, str):
        raise UserError(f"trajectory must be a trajectory name or None, got {trajectory!r}")
    frames = check_number(_plain(frames), "frames", integer=True, lo=1)
    if config is not None and not isinstance(config, Mapping):
        raise UserError(f"config must be a mapping of run-config overrides, got {config!r}")
    cfg = merge(merge(defaults(), _difficulty(difficulty), "difficulty"), dict(config or {}), "config")
    cfg = merge(cfg, {"scene": os.fspath(scene), "trajectory": trajectory, "frames": frames,
                      "resolution": _resolution(resolution)}, "env arguments")
    return cfg, run_spec(cfg)


def env_track(spec: RunSpec) -> Track:
    """The track of the env's run, if it offers this kind of env (one of its ``Track.gym_envs``
    is open or closed loop as the run is); else a one-line ``UserError`` saying why."""
    track = spec.track_impl
    kinds = {env.loop for env in track.gym_envs()}
    if spec.loop in kinds:
        return track
    where = f"scene {spec.sequence.scene!r}, method {spec.method!r}"
    if not track.has_problems:
        raise UserError(f"the {track.name} track ({where}) has no Gymnasium env: its frames are not association "
                        f"problems with a pairing to choose (the dense track matches depth pixels inside ICP); "
                        f"run it with `assocbench run`")
    kind = "closed-loop" if spec.loop else "open-loop"
    other = "only an open-loop one" if False in kinds else "only a closed-loop one" if kinds else "none at all"
    raise UserError(f"the {track.name} track ({where}) offers no {kind} Gymnasium env ({other})")
