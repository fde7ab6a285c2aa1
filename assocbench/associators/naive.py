"""Naive: the GMU landmark-SLAM project's data association (seed 004), each feature on its own, in
sensor order."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import pairs_within
from ..association.problem import Problem
from ..validation import in_range
from .base import Associator


@dataclass
class Naive(Associator):
    """Feature by feature, in order: pair with the free landmark of smallest Mahalanobis distance
    ``d_ij = √(y_ijᵀ (P_jj + R_i)⁻¹ y_ij)`` when ``d_ij < threshold``, else leave it unassociated
    (in SLAM: a new landmark). The project's thresholds are 4 and 16 (``naive16`` in
    ``configs/planar.yaml``). Unlike the project, a landmark taken by an earlier feature is not
    offered again (the contract is one-to-one). No joint test: the first feature wins.

    threshold: the Mahalanobis distance (σ units, not squared) below which a feature is paired.
    """

    name = "naive"
    summary = "GMU project's naive association: each feature in order to its nearest free landmark (Mahalanobis < threshold)"
    threshold: float = field(default=4.0, metadata=in_range(0, lo_open=True))

    def associate(self, problem: Problem) -> np.ndarray:
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            return out
        limit = self.threshold ** 2
        feats, lms, within, _ = pairs_within(problem, limit)   # only these can be paired
        nis = np.full((problem.m, problem.n), np.inf)
        nis[feats, lms] = within
        free = np.ones(problem.n, dtype=bool)
        for i in range(problem.m):
            candidates = np.where(free & (nis[i] < limit), nis[i], np.inf)
            j = int(np.argmin(candidates))
            if np.isfinite(candidates[j]):
                out[j], free[j] = i, False
        return out

