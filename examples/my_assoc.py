"""A complete third-party associator: the plugin example of the README.

Run it with:  PYTHONPATH=examples assocbench run --method my_assoc:GatedNearest
"""

from dataclasses import dataclass, field

import numpy as np

from assocbench import Associator
from assocbench.association.compatibility import individually_compatible, pairwise_nis
from assocbench.validation import in_range


@dataclass
class GatedNearest(Associator):
    """Landmarks in order of their best NIS each take their nearest free feature inside the gate.

    confidence: individual gate χ²_d(confidence).
    """

    name = "gated-nearest"
    summary = "each landmark takes its nearest free feature inside the chi-square gate"
    confidence: float = field(default=0.95, metadata=in_range(0, 1, lo_open=True, hi_open=True))

    def associate(self, problem):
        out = np.full(problem.n, -1)
        if problem.m == 0 or problem.n == 0:
            return out
        nis, _ = pairwise_nis(problem)
        nis[~individually_compatible(problem, self.confidence, nis)] = np.inf
        for j in np.argsort(nis.min(axis=0), kind="stable"):
            i = int(np.argmin(nis[:, j]))
            if np.isfinite(nis[i, j]):
                out[j] = i
                nis[i, :] = np.inf  # one feature, one landmark
        return out
