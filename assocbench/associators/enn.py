"""ENN: Euclidean nearest neighbour with a gate, greedy by distance, one-to-one."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import innovations
from ..association.problem import Problem
from ..validation import in_range
from .base import Associator, greedy_one_to_one


@dataclass
class ENN(Associator):
    """Pair by Euclidean distance ``||wrap(z_i - zhat_j)||`` ignoring all uncertainty.

    gate: largest accepted distance, in measurement units (pixels for the camera track).
    """

    name = "enn"
    summary = "Euclidean nearest neighbour, distance gate, greedy one-to-one"
    gate: float = field(default=25.0, metadata=in_range(0, lo_open=True))

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        dist = np.linalg.norm(innovations(problem), axis=2)
        return greedy_one_to_one(dist, dist <= self.gate)
