"""MNN: Mahalanobis nearest neighbour with a χ² individual-compatibility gate, greedy."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import individually_compatible, pairwise_nis
from ..association.problem import Problem
from .base import CONFIDENCE, Associator, greedy_one_to_one


@dataclass
class MNN(Associator):
    """Pair by smallest individual NIS ``y_ijᵀ (P_jj + R_i)⁻¹ y_ij`` among pairs inside the gate.

    confidence: gate ``χ²_d(confidence)`` on the individual NIS.
    """

    name = "mnn"
    summary = "Mahalanobis nearest neighbour, chi-square gate, greedy one-to-one"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        nis, _ = pairwise_nis(problem)
        return greedy_one_to_one(nis, individually_compatible(problem, self.confidence, nis))
