"""SNN: surprisal nearest neighbour (lab 8, section 3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..association.compatibility import LOG_2PI, JointFactor, chi2_threshold, individually_compatible, pairwise_nis
from ..association.problem import Problem
from .base import Associator


@dataclass
class SNN(Associator):
    """Grow the association one pairing at a time, always adding the individually compatible
    pairing that lowers the total surprisal ``s(A) = n_U log|Y| - log N(y_A; 0, S_A)`` most while
    keeping the hypothesis jointly compatible; stop when no pairing lowers it.

    Adding a pairing changes the surprisal by ``Δs = -log|Y| + ½ (ΔNIS + Δlog det + d log 2π)``.

    confidence: individual and joint gates ``χ²_{d k}(confidence)``.
    """

    name = "snn"
    summary = "surprisal nearest neighbour: greedy surprisal descent with IC and JC kept"
    confidence: float = 0.99

    def associate(self, problem: Problem) -> np.ndarray:
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            return out
        ic = individually_compatible(problem, self.confidence, pairwise_nis(problem)[0])
        factor = JointFactor(problem)
        log_volume = float(np.log(problem.volume))
        while True:
            feats, lms = np.nonzero(ic)
            if not len(feats):
                break
            dnis, dlogdet = factor.candidates(lms, feats)
            gain = -log_volume + 0.5 * (dnis + dlogdet + problem.d * LOG_2PI)
            joint_ok = factor.nis + dnis <= chi2_threshold(problem.d * (factor.k + 1), self.confidence)
            gain = np.where(joint_ok, gain, np.inf)
            best = int(np.argmin(gain))
            if not gain[best] < 0:
                break
            i, j = feats[best], lms[best]
            factor.push(i, j)
            out[j] = i
            ic[i, :] = False
            ic[:, j] = False
        return out
