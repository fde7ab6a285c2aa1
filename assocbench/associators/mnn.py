"""MNN: Mahalanobis nearest neighbour with a χ² individual-compatibility gate, greedy."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..association.compatibility import chi2_threshold, pairs_within_kernel, wrap_mask
from ..association.problem import Problem
from .base import CONFIDENCE, Associator, sorted_greedy


@dataclass
class MNN(Associator):
    """Pair by smallest individual NIS ``y_ijᵀ (P_jj + R_i)⁻¹ y_ij`` among pairs inside the gate
    (``gated_pairs``: only the pairs the exact prefilter lets through are whitened), greedily
    (``greedy_pairs``), in one compiled call (``_gate_then_greedy``).

    confidence: gate ``χ²_d(confidence)`` on the individual NIS.
    """

    name = "mnn"
    summary = "Mahalanobis nearest neighbour, chi-square gate, greedy one-to-one"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        return _gate_then_greedy(problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                                 chi2_threshold(problem.d, self.confidence))


@njit(cache=True)
def _gate_then_greedy(P, z, zhat, R, wrap, limit):
    """``greedy_pairs`` on ``gated_pairs``' pairs (NIS ``<= limit``) in one dispatch, no pair list
    boxed for Python."""
    feats, lms, nis, _ = pairs_within_kernel(P, z, zhat, R, wrap, limit, False)
    return sorted_greedy(feats, lms, nis, z.shape[0], zhat.shape[0])
