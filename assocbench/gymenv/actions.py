"""Valid actions for ``AssociationEnv``: the action mask it publishes and two ways to sample with it.

The action is a ``MultiDiscrete`` of N slots taking values -1..M-1 (``start=-1``), so value
``v`` of slot ``j`` is column ``v + 1`` of row ``j`` of ``info["action_mask"]`` (N, M+1), int8:

* a real candidate slot (``j < n``) may take -1 or any real feature ``0..m-1``;
* a padded slot (``j >= n``) may take only -1.

``env.action_space.sample(mask=sample_mask(info["action_mask"]))`` (Gymnasium's masked
sampling for ``MultiDiscrete``; in a vector env, per env from ``envs.single_action_space``) therefore never uses a padded slot or a feature index beyond
the frame, but it draws each slot independently, so two candidates can still pick the same
feature (an invalid action). ``sample_valid_action`` draws a fully valid, one-to-one action.
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
    """One env's (N, M+1) ``mask`` as the tuple of int8 rows that ``MultiDiscrete.sample(mask=...)``
    takes. A vector env's action space is a ``Box`` with no masked sampling: sample each env from
    ``envs.single_action_space`` with its own row of the stacked ``info["action_mask"]``."""
    mask = np.asarray(mask, dtype=np.int8)
    if mask.ndim != 2:
        raise ValueError(f"one env's action mask is (N, M+1), got shape {mask.shape}")
    return tuple(mask)


def sample_valid_action(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random action that the env accepts: every slot takes an allowed value and no feature
    is used twice. Slots are visited in random order; each takes -1 or a feature not yet
    taken, uniformly among those (so the draw is valid but not uniform over all matchings).
    A (num_envs, N, M+1) stack gives one action per env."""
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
