"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and incremental."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import individually_compatible, joint_gates, pairwise_nis, wrap_mask
from ..association.problem import Problem
from ..validation import in_range
from .base import CONFIDENCE, Associator
from .jcbb_search import jcbb_search


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Pairs must pass the individual gate ``χ²_d(c)``; landmarks without an individually
    compatible partner leave the search. Depth first (compiled, ``jcbb_search``), each node
    takes the remaining landmark with the fewest feasible features (ties: the smallest least
    NIS increase) and tries, in order, the pairings that keep the hypothesis jointly
    compatible (smallest NIS increase first), leaving
    it unassociated, and the pairings that break the joint test for now (a later, larger
    hypothesis may pass its looser gate). The first dive is thus the classic JCBB dive. The
    joint factor grows incrementally (``compatibility.append_rows``) and keeps every landmark's
    conditional moments per hypothesis size, so each node evaluates all remaining
    pairings against it (forward checking). With ``k`` pairings, NIS ``ν`` and bound ``b`` on
    further pairings:

    * a pairing with ``ν + Δν > χ²_{d(k+b)}(c)`` can never complete a jointly compatible
      hypothesis (NIS never decreases as pairings are added), so it leaves the subtree;
    * ``b`` is the maximum matching of the feasible pairings, lowered while
      ``ν + δ_b > χ²_{d(k+b)}(c)``, where ``δ_b`` is the b-th smallest least increment per
      landmark (and per feature): b more pairings need b distinct landmarks, and the final NIS
      is at least ``NIS(H + p)`` for each of its pairings ``p``;
    * a node is cut when ``k + b`` is below the best count, or equal to it while ``ν + δ_b`` is
      no lower than the best NIS (so branches that can tie the best are explored).

    A hypothesis counts when its own NIS passes ``χ²_{dk}(c)``, so the result is exactly
    the hypothesis of an exhaustive search. ``prefix_test=True`` also demands that every
    partial hypothesis pass its own test, as in the original paper (smaller tree; it can miss
    a hypothesis whose prefix fails the tighter gate).

    confidence: individual and joint gate ``c``.
    max_nodes: node budget; when spent the best hypothesis so far is returned and
        ``info["timed_out"]`` is True.
    prefix_test: apply the joint test to every partial hypothesis (classic JCBB).
    """

    name = "jcbb"
    summary = "joint compatibility branch and bound: most jointly compatible pairings, then lowest NIS"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    max_nodes: int = field(default=10_000, metadata=in_range(1))
    prefix_test: bool = False

    def associate(self, problem: Problem) -> np.ndarray:
        out = self.empty(problem)
        self.info = {"timed_out": False, "nodes": 0}
        if problem.m == 0 or problem.n == 0:
            return out
        ic = individually_compatible(problem, self.confidence, pairwise_nis(problem)[0])
        gate = joint_gates(problem.d, problem.n, self.confidence)
        feats, lms, nodes, timed_out = jcbb_search(ic, problem.P, problem.z, problem.zhat, problem.R,
                                                   wrap_mask(problem), gate, int(self.max_nodes), bool(self.prefix_test))
        out[lms] = feats
        self.info = {"timed_out": bool(timed_out), "nodes": int(nodes)}
        return out
