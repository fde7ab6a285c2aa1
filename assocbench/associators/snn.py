"""SNN: surprisal nearest neighbour (lab 8, section 3)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..association.compatibility import (
    LOG_2PI,
    advance_moments,
    append_rows,
    empty_factor,
    individually_compatible,
    joint_gates,
    whitened_pair,
    wrap_mask,
)
from ..association.problem import Problem
from .base import CONFIDENCE, Associator


@dataclass
class SNN(Associator):
    """Grow the association one pairing at a time, adding the compatible pairing that lowers the
    total surprisal ``s(A) = n_U log|Y| - log N(y_A; 0, S_A)`` most while the hypothesis stays
    jointly compatible; stop when none lowers it. A pairing changes it by
    ``Δs = -log|Y| + ½ (ΔNIS + Δlog det + d log 2π)``, tested against the growing joint factor
    (``snn_greedy``, compiled).

    confidence: individual and joint gates ``χ²_{d k}(confidence)``.
    """

    name = "snn"
    summary = "surprisal nearest neighbour: greedy surprisal descent with IC and JC kept"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)

    def associate(self, problem: Problem) -> np.ndarray:
        problem.validate()              # reads P's cross terms (a no-op once checked)
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            return out
        ic = individually_compatible(problem, self.confidence)
        gate = joint_gates(problem.d, problem.n, self.confidence)
        new_cost = -float(np.log(problem.volume)) + 0.5 * problem.d * LOG_2PI
        feats, lms = snn_greedy(ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem), gate, new_cost)
        out[lms] = feats
        return out


@njit(cache=True)
def snn_greedy(ic, P, z, zhat, R, wrap, gate, new_cost):
    """Pairings (features, landmarks) of the greedy descent: each step takes, in (feature, landmark)
    order, the first pair with the lowest ``Δs = new_cost + ½ (ΔNIS + Δlog det)`` keeping
    ``NIS ≤ gate[k + 1]``; stops when no ``Δs`` is negative."""
    m, n = ic.shape
    d = z.shape[1]
    Mt, w, C, G, S, y, L, w2 = empty_factor(n, d)
    open_f = np.ones(m, np.bool_)
    open_l = np.ones(n, np.bool_)
    pairs_i = np.empty(min(m, n), np.int64)
    pairs_j = np.empty(min(m, n), np.int64)
    k, nis = 0, 0.0
    while True:
        best, best_i, best_j, best_dn = 0.0, -1, -1, 0.0
        for i in range(m):
            if not open_f[i]:
                continue
            for j in range(n):
                if not (open_l[j] and ic[i, j]):
                    continue
                dn, dlogdet = whitened_pair(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
                gain = new_cost + 0.5 * (dn + dlogdet)
                if nis + dn <= gate[k + 1] and gain < best:
                    best, best_i, best_j, best_dn = gain, i, j, dn
        if best_i < 0:
            break
        whitened_pair(P, z, zhat, R, wrap, best_i, best_j, C, G, S, y, L, w2)   # L, w2 of the winner
        open_f[best_i], open_l[best_j] = False, False
        cols = np.flatnonzero(open_l)
        append_rows(Mt, w, k * d, P, best_j, L, w2, cols)
        advance_moments(Mt, k * d, w2, cols, C, G, C, G)
        pairs_i[k], pairs_j[k] = best_i, best_j
        k += 1
        nis += best_dn
    return pairs_i[:k], pairs_j[:k]
