"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and incremental."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from ..association.compatibility import JointFactor, chi2_threshold, individually_compatible, pairwise_nis
from ..association.problem import Problem
from .base import Associator


class _BudgetExceeded(Exception):
    pass


def _count_bound(rows: np.ndarray, cols: np.ndarray) -> int:
    """min(#distinct rows, #distinct cols): a cheap upper bound on a matching's size."""
    if not len(rows):
        return 0
    return int(min(np.count_nonzero(np.bincount(rows)), np.count_nonzero(np.bincount(cols))))


def _max_matching(rows: np.ndarray, cols: np.ndarray) -> int:
    """Size of a maximum bipartite matching of the pairs (rows[q], cols[q]) (Hopcroft-Karp)."""
    if not len(rows):
        return 0
    r, ri = np.unique(rows, return_inverse=True)
    c, ci = np.unique(cols, return_inverse=True)
    if min(len(r), len(c)) == len(rows) or len(r) == 1 or len(c) == 1:
        return min(len(r), len(c))
    graph = csr_matrix((np.ones(len(rows), np.int8), (ri, ci)), shape=(len(r), len(c)))
    return int((maximum_bipartite_matching(graph, perm_type="column") >= 0).sum())


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Pairs must pass the individual gate ``χ²_d(c)``; landmarks and features without an
    individually compatible partner leave the search. Depth first, each node takes the
    remaining landmark with the fewest feasible features and tries them (smallest joint NIS
    increase first), then leaves it unassociated. The joint factor grows incrementally
    (``JointFactor``), and every node evaluates all remaining pairings against it at once
    (forward checking). With ``k`` pairings, NIS ``ν`` and bound ``b`` on further pairings:

    * a pairing with ``ν + Δν > χ²_{d(k+b)}(c)`` can never complete a jointly compatible
      hypothesis (NIS never decreases as pairings are added), so it leaves the subtree; ``b``
      counts the landmarks and free features that keep a feasible pairing, recomputed until
      stable;
    * a node is cut when ``k + b`` is below the best count found, or equal to it while ``ν``
      is already no lower than the best NIS (branches that can tie are explored).

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
    confidence: float = 0.99
    max_nodes: int = 3_000
    prefix_test: bool = False

    def associate(self, problem: Problem) -> np.ndarray:
        self.info = {"timed_out": False, "nodes": 0}
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            return out
        self._ic = individually_compatible(problem, self.confidence, pairwise_nis(problem)[0])
        self._factor = JointFactor(problem)
        self._free = np.ones(problem.m, bool)
        self._gate = np.array([chi2_threshold(problem.d * k, self.confidence) for k in range(problem.n + 1)])
        self._best = (0, 0.0, [])
        try:
            self._search(self._ic.any(axis=0))
        except _BudgetExceeded:
            self.info["timed_out"] = True
        for i, j in self._best[2]:
            out[j] = i
        return out

    def _record(self) -> None:
        f = self._factor
        best_k, best_nis, _ = self._best
        if f.nis <= self._gate[f.k] and (f.k > best_k or (f.k == best_k and f.nis < best_nis)):
            self._best = (f.k, f.nis, list(f.pairs))

    def _feasible(self, remaining: np.ndarray):
        """Pairings of remaining landmarks with free features that can still end jointly
        compatible, and the bound on further pairings."""
        f = self._factor
        feats, cols = np.nonzero(self._ic[:, remaining] & self._free[:, None])
        lms = np.flatnonzero(remaining)[cols]
        if not len(feats):
            return feats, lms, None, 0
        dnis, dlogdet, ext = f.candidates(lms, feats)
        keep = np.ones(len(feats), bool)
        bound = None
        while True:
            new_bound = _count_bound(lms[keep], feats[keep])
            if new_bound == bound:
                break
            bound = new_bound
            keep &= f.nis + dnis <= self._gate[f.k + bound]
        if bound and f.k + bound >= self._best[0]:  # the exact matching bound only where it may cut
            bound = _max_matching(lms[keep], feats[keep])
        return feats[keep], lms[keep], (dnis[keep], dlogdet[keep], ext, np.flatnonzero(keep)), bound

    def _search(self, remaining: np.ndarray) -> None:
        self.info["nodes"] += 1
        if self.info["nodes"] > self.max_nodes:
            raise _BudgetExceeded
        f = self._factor
        self._record()
        feats, lms, cand, bound = self._feasible(remaining)
        best_k, best_nis, _ = self._best
        if bound == 0 or f.k + bound < best_k or (f.k + bound == best_k and f.nis >= best_nis):
            return
        dnis, dlogdet, ext, rows = cand
        counts = np.bincount(lms, minlength=len(remaining))
        j = int(np.flatnonzero(counts == counts[counts > 0].min())[0])
        still = np.zeros_like(remaining)
        still[np.unique(lms)] = True          # landmarks without a feasible pairing leave for good
        still[j] = False
        mine = np.flatnonzero(lms == j)
        limit = self._gate[f.k + 1] if self.prefix_test else np.inf
        for a in mine[np.argsort(dnis[mine], kind="stable")]:
            if f.nis + dnis[a] > limit:
                break
            i = feats[a]
            f.push(i, j, ext, rows[a], dnis[a], dlogdet[a])
            self._free[i] = False
            self._search(still)
            self._free[i] = True
            f.pop()
        self._search(still)
