"""Gymnasium environments, their ids from the track registry (``GymEnvs``): per shipped scene
``assocbench/<Scene>-v0`` (open loop) and ``assocbench/<Scene>Loop-v0`` (closed loop: the track's
estimator updated with the agent's actions), e.g. ``assocbench/Room-v0``,
``assocbench/ParkLoop-v0``; ``env_ids()`` lists them. Importing this package registers them (or
``gymnasium.make("assocbench.gymenv:assocbench/Room-v0")``); a track registered later gets its ids
from ``register_envs()``."""

from __future__ import annotations

import gymnasium as gym

from ..errors import UserError
from ..tracks.capabilities import GymEnv, GymEnvs, has
from ..tracks.registry import iter_tracks
from .actions import action_mask, sample_mask, sample_valid_action
from .env import AssociationEnv, classical_action
from .loop_env import LoopAssociationEnv

ENTRY_POINTS = {False: "assocbench.gymenv.env:AssociationEnv", True: "assocbench.gymenv.loop_env:LoopAssociationEnv"}


def env_ids() -> dict[str, tuple[str, GymEnv]]:
    """Every registered track's envs: id -> (track name, ``GymEnv``), in registry order; an id two
    tracks declare is a one-line ``UserError``."""
    out: dict[str, tuple[str, GymEnv]] = {}
    for track in iter_tracks():
        for env in (track.gym_envs() if has(track, GymEnvs) else ()):
            if env.id in out and out[env.id][0] != track.name:
                raise UserError(f"Gymnasium env id {env.id} is declared by the {out[env.id][0]} and {track.name} "
                                "tracks: rename one track's scene")
            out[env.id] = (track.name, env)
    return out


def register_envs() -> None:
    """Register every track's envs with Gymnasium (idempotent: ids already registered are kept)."""
    for env_id, (name, env) in env_ids().items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY_POINTS[env.loop], kwargs={"scene": env.scene, "track": name})


__all__ = ["AssociationEnv", "LoopAssociationEnv", "action_mask", "classical_action", "env_ids", "register_envs",
           "sample_mask", "sample_valid_action"]

register_envs()
