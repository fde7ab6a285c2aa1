"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and incremental."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..association.compatibility import JointFactor, chi2_threshold, individually_compatible, pairwise_nis
from ..association.problem import Problem
from .base import Associator


class _BudgetExceeded(Exception):
    pass


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Depth-first over candidate landmarks (fewest individually compatible features first),
    each either paired with a free compatible feature (smallest joint NIS increase first) or
    left unassociated. Pairs must pass the individual gate ``χ²_d(c)``; landmarks and features
    with no compatible partner leave the search. The joint factor grows incrementally
    (``JointFactor``). A branch is cut when

    * it cannot pair more than the best hypothesis found (the bound counts the remaining
      landmarks and free features that still have a compatible partner), or can only tie it
      while its NIS is already no lower (NIS never decreases as pairings are added); or
    * its NIS exceeds ``χ²_{d(k+b)}(c)`` for ``k`` pairings and bound ``b``: no completion
      can be jointly compatible.

    A hypothesis counts when its own NIS passes ``χ²_{dk}(c)``. This returns exactly the
    hypothesis of an exhaustive search. With ``prefix_test=True`` every partial hypothesis must
    pass its own test, as in the original paper (faster, may miss a hypothesis whose prefix
    fails the tighter gate).

    confidence: individual and joint gate ``c``.
    max_nodes: node budget; when spent, the best hypothesis so far is returned and
        ``info["timed_out"]`` is True.
    prefix_test: apply the joint test to every partial hypothesis (classic JCBB).
    """

    name = "jcbb"
    summary = "joint compatibility branch and bound: most jointly compatible pairings, then lowest NIS"
    confidence: float = 0.99
    max_nodes: int = 200_000
    prefix_test: bool = False

    def associate(self, problem: Problem) -> np.ndarray:
        self.info = {"timed_out": False, "nodes": 0}
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        ic = individually_compatible(problem, self.confidence, pairwise_nis(problem)[0])
        ic[:, ~ic.any(axis=0)] = False
        order = np.flatnonzero(ic.any(axis=0))
        order = order[np.argsort(ic[:, order].sum(axis=0), kind="stable")]
        self._problem, self._ic, self._order = problem, ic, order
        self._factor = JointFactor(problem)
        self._used = np.zeros(problem.m, bool)
        self._gate = np.array([chi2_threshold(problem.d * k, self.confidence) for k in range(len(order) + 1)])
        self._best = (0, 0.0, [])
        try:
            self._search(0)
        except _BudgetExceeded:
            self.info["timed_out"] = True
        out = self.empty(problem)
        for i, j in self._best[2]:
            out[j] = i
        return out

    def _bound(self, t: int) -> int:
        """Most pairings still possible among landmarks ``order[t:]`` and the free features."""
        sub = self._ic[~self._used][:, self._order[t:]]
        return int(min(sub.any(axis=0).sum(), sub.any(axis=1).sum()))

    def _record(self) -> None:
        f = self._factor
        best_k, best_nis, _ = self._best
        if f.nis <= self._gate[f.k] and (f.k > best_k or (f.k == best_k and f.nis < best_nis)):
            self._best = (f.k, f.nis, list(f.pairs))

    def _search(self, t: int) -> None:
        self.info["nodes"] += 1
        if self.info["nodes"] > self.max_nodes:
            raise _BudgetExceeded
        f = self._factor
        self._record()
        if t == len(self._order):
            return
        bound = self._bound(t)
        best_k, best_nis, _ = self._best
        if f.k + bound < best_k or (f.k + bound == best_k and f.nis >= best_nis):
            return
        if f.nis > self._gate[f.k + bound]:
            return
        j = self._order[t]
        feats = np.flatnonzero(self._ic[:, j] & ~self._used)
        if len(feats):
            dnis, dlogdet, ext = f.candidates(np.full(len(feats), j), feats)
            limit = self._gate[f.k + 1] if self.prefix_test else self._gate[f.k + bound]
            for a in np.argsort(dnis, kind="stable"):
                if f.nis + dnis[a] > limit:
                    break
                f.push(feats[a], j, ext, a, dnis[a], dlogdet[a])
                self._used[feats[a]] = True
                self._search(t + 1)
                self._used[feats[a]] = False
                f.pop()
        self._search(t + 1)

