"""MNN: Mahalanobis nearest neighbour with a χ² individual-compatibility gate, greedy."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import gated_pairs
from ..association.problem import Problem
from .base import CONFIDENCE, Associator, greedy_pairs


@dataclass
class MNN(Associator):
    """Pair by smallest individual NIS ``y_ijᵀ (P_jj + R_i)⁻¹ y_ij`` among pairs inside the gate
    (``gated_pairs``: only the pairs the exact prefilter lets through are whitened), greedily.

    confidence: gate ``χ²_d(confidence)`` on the individual NIS.
    """

    name = "mnn"
    summary = "Mahalanobis nearest neighbour, chi-square gate, greedy one-to-one"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        feats, lms, nis, _ = gated_pairs(problem, self.confidence)
        return greedy_pairs(feats, lms, nis, problem.m, problem.n)
