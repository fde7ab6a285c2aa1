"""Valid actions for ``AssociationEnv``. The action is a ``MultiDiscrete`` of N slots in -1..M-1
(``start=-1``), so value ``v`` of slot ``j`` is column ``v + 1`` of row ``j`` of
``info["action_mask"]`` (N, M+1, int8): a real candidate slot (``j < n``) may take -1 or a real
feature, a padded one only -1. ``env.action_space.sample(mask=sample_mask(info["action_mask"]))``
never uses a padded slot or a missing feature, but two candidates may pick one feature;
``sample_valid_action`` draws a valid one-to-one action.
"""

from __future__ import annotations

import numpy as np

from ..association.problem import NO_MATCH


def action_mask(n: int, m: int, max_landmarks: int, max_features: int) -> np.ndarray:
    """The (N, M+1) int8 mask of a frame with ``n`` candidates and ``m`` features (module docstring)."""
    mask = np.zeros((max_landmarks, max_features + 1), dtype=np.int8)
    mask[:, 0] = 1                   # -1, "no pairing", is always allowed
    mask[:n, 1:m + 1] = 1
    return mask


def sample_mask(mask: np.ndarray) -> tuple[np.ndarray, ...]:
    """One env's ``mask`` as the tuple of int8 rows ``MultiDiscrete.sample(mask=...)`` takes (a
    vector env samples each env from ``envs.single_action_space`` with its row)."""
    mask = np.asarray(mask, dtype=np.int8)
    if mask.ndim != 2:
        raise ValueError(f"one env's action mask is (N, M+1), got shape {mask.shape}")
    return tuple(mask)


def sample_valid_action(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random action the env accepts: slots in random order, each taking -1 or a free feature
    uniformly (valid, not uniform over matchings). A (num_envs, N, M+1) stack gives one per env."""
    mask = np.asarray(mask)
    if mask.ndim == 3:
        return np.stack([sample_valid_action(rows, rng) for rows in mask])
    if mask.ndim != 2:
        raise ValueError(f"an action mask is (N, M+1) or (num_envs, N, M+1), got shape {mask.shape}")
    action = np.full(mask.shape[0], NO_MATCH, dtype=np.int64)
    free = np.ones(mask.shape[1] - 1, dtype=bool)
    for j in rng.permutation(mask.shape[0]):
        choices = np.flatnonzero((mask[j, 1:] == 1) & free)
        pick = rng.integers(len(choices) + 1)     # len(choices) stands for -1
        if pick < len(choices):
            action[j] = choices[pick]
            free[choices[pick]] = False
    return action
