"""Gymnasium environments: ``gymnasium.make("assocbench/Room-v0")`` and one id per shipped scene."""

from __future__ import annotations

import gymnasium as gym

from .actions import action_mask, sample_mask, sample_valid_action
from .env import AssociationEnv, classical_action

ENV_IDS = {"Room": "room", "Checkerboard": "checkerboard", "Corridor": "corridor"}


def register_envs() -> None:
    """Register ``assocbench/<Scene>-v0`` for every shipped scene (idempotent)."""
    for name, scene in ENV_IDS.items():
        env_id = f"assocbench/{name}-v0"
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="assocbench.gymenv.env:AssociationEnv", kwargs={"scene": scene})


__all__ = ["AssociationEnv", "ENV_IDS", "action_mask", "classical_action", "register_envs", "sample_mask",
           "sample_valid_action"]
