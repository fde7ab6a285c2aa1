"""LSA: optimal linear sum assignment on negative log-likelihood with dummy columns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..association.compatibility import gated_pairs, log_gaussian
from ..association.problem import NO_MATCH, Problem
from .base import CONFIDENCE, Associator

FORBIDDEN = 1e12  # finite stand-in for +inf so the assignment is always feasible


@dataclass
class LSA(Associator):
    """Minimise ``Σ -log N(z_i; zhat_j, P_jj + R_i)`` over one-to-one pairings, each landmark
    having a private dummy "unassociated" column of cost ``threshold``.

    threshold: cost of leaving a landmark unassociated; ``None`` uses ``log|Y|``
        (the surprisal of an unassociated landmark).
    confidence: pairs outside the individual gate ``χ²_d(confidence)`` are forbidden.
    """

    name = "lsa"
    summary = "linear sum assignment on -log-likelihood with dummy unassociated columns"
    threshold: float | None = None
    confidence: float = field(default=0.99, metadata=CONFIDENCE)

    def associate(self, problem: Problem) -> np.ndarray:
        m, n = problem.m, problem.n
        if m == 0 or n == 0:
            return self.empty(problem)
        feats, lms, nis, logdet = gated_pairs(problem, self.confidence)
        cost = np.full((n, m + n), FORBIDDEN)
        cost[lms, feats] = -log_gaussian(nis, logdet, problem.d)
        dummy = np.log(problem.volume) if self.threshold is None else self.threshold
        cost[np.arange(n), m + np.arange(n)] = dummy
        rows, cols = linear_sum_assignment(cost)
        out = np.full(n, NO_MATCH, dtype=np.int64)
        real = (cols < m) & (cost[rows, cols] < FORBIDDEN)
        out[rows[real]] = cols[real]
        return out
