"""Gymnasium environments: ``gymnasium.make("assocbench/Room-v0")`` and one id per shipped scene
(open loop: the belief is sampled around the truth), and ``assocbench/RoomLoop-v0`` and friends
(closed loop: the belief is a filter updated with the agent's own actions).

Importing this package registers them: ``import assocbench.gymenv``, or name the module in the
id, ``gymnasium.make("assocbench.gymenv:assocbench/Room-v0")``."""

from __future__ import annotations

import gymnasium as gym

from .actions import action_mask, sample_mask, sample_valid_action
from .env import AssociationEnv, classical_action
from .loop_env import LoopAssociationEnv

ENV_IDS = {"Room": "room", "Checkerboard": "checkerboard", "Corridor": "corridor"}


def register_envs() -> None:
    """Register ``assocbench/<Scene>-v0`` and ``assocbench/<Scene>Loop-v0`` for every shipped
    scene (idempotent)."""
    entry_points = {"": "assocbench.gymenv.env:AssociationEnv",
                    "Loop": "assocbench.gymenv.loop_env:LoopAssociationEnv"}
    for name, scene in ENV_IDS.items():
        for suffix, entry_point in entry_points.items():
            env_id = f"assocbench/{name}{suffix}-v0"
            if env_id not in gym.registry:
                gym.register(id=env_id, entry_point=entry_point, kwargs={"scene": scene})


__all__ = ["AssociationEnv", "ENV_IDS", "LoopAssociationEnv", "action_mask", "classical_action", "register_envs",
           "sample_mask", "sample_valid_action"]

register_envs()
