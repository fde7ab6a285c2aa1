"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and anytime."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..association.compatibility import (
    chi2_threshold,
    gate_mask,
    gated_pairs,
    individually_compatible,
    joint_gates,
    wrap_mask,
)
from ..association.problem import Problem
from ..validation import in_range
from .anytime_search import Incumbent, anytime_jcbb, budget_tables, default_budget, later_steps
from .base import CONFIDENCE, Associator
from .jcbb_dive import classic_dive
from .jcbb_quick import quick_jcbb_into
from .lsa import LSA
from .rjc import RJC

__all__ = ["JCBB", "anytime_jcbb", "default_budget"]


@lru_cache(maxsize=1024)
def _call_tables(d: int, n: int, confidence: float, max_nodes: int | None) -> tuple:
    """(``χ²_d(c)``, ``joint_gates``, ``budget_tables``' two) of a call: one cached lookup instead
    of three."""
    return (chi2_threshold(d, confidence), joint_gates(d, n, confidence), *budget_tables(n, max_nodes))


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS; pairs must pass the
    individual gate ``χ²_d(c)``. Anytime, in three steps, each from the best hypothesis so far:

    1. **Quick exact search, then the classic first dive** (``jcbb_quick``): about 30 nodes per
       candidate prove most small problems; where they do not, classic JCBB's first dive runs in
       full, so an answer is never worse than it.
    2. **More starts**, each kept if better: a global greedy dive, ``REORDERED_DIVES`` dives ordered
       surest first by the previous answer (``NIS(H + p) - NIS(H)``), a fail-first dive, a dive
       guided by the optimal assignment, and RJC's seeded restarts (so never below RJC with the same
       seed). A wrong early pairing starves a dive; sure pairings first and clean samples fix the
       shallow levels (``benchmarks/jcbb_anytime.py``).
    3. **Branch and bound** (``jcbb_search``) with the budget left: branch on the landmark with the
       fewest feasible features; try the jointly compatible pairings (smallest NIS increase first),
       then none, then those that break the test for now (a larger hypothesis has a looser gate),
       with forward checking. With ``k`` pairings, NIS ``ν`` and bound ``b``:

       * a pairing with ``ν + Δν > χ²_{d(k+b)}(c)`` leaves the subtree (NIS never decreases with pairings);
       * ``b``: the maximum matching of the feasible pairings, lowered while ``ν + δ_b > χ²_{d(k+b)}(c)`` (``δ_b``: the b-th smallest least increment per landmark and per feature);
       * a node is cut when ``k + b`` is below the best count, or equal with ``ν + δ_b`` no lower than the best NIS.

    A hypothesis counts when its NIS passes ``χ²_{dk}(c)``, so a search ending within budget returns
    the exhaustive answer (``info["proven_optimal"]``). ``prefix_test=True`` tests every partial
    hypothesis, as the paper does (never proven).

    confidence: individual and joint gate ``c``.
    max_nodes: node budget (dives count a node per landmark); the classic dive always runs, later
        steps while there is room; when spent, the incumbent with ``info["timed_out"]``. None:
        ``default_budget`` plus the quick search's nodes.
    prefix_test: apply the joint test to every partial hypothesis (classic JCBB).

    ``info``: ``timed_out``, ``proven_optimal``, ``nodes``, ``dive_pairings`` (None if no dive ran),
    ``history`` (``(nodes, pairings, NIS)`` per improvement).
    """

    name = "jcbb"
    summary = "joint compatibility branch and bound: most jointly compatible pairings, then lowest NIS"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    max_nodes: int | None = field(default=None, metadata=in_range(1))
    prefix_test: bool = False

    def associate(self, problem: Problem) -> np.ndarray:
        problem.validate()              # reads P's cross terms (a no-op once checked)
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            self.info = {"timed_out": False, "proven_optimal": True, "nodes": 0, "dive_pairings": 0, "history": []}
            return out
        wrap = wrap_mask(problem)
        max_nodes = None if self.max_nodes is None else int(self.max_nodes)
        limit, gate, quick, budget = _call_tables(problem.d, problem.n, self.confidence, max_nodes)
        nis, nodes, timed_out, dive_k, history = quick_jcbb_into(
            out, problem.P, problem.z, problem.zhat, problem.R, wrap, limit, gate, quick, budget,
            bool(self.prefix_test))
        if not timed_out:       # proven by the quick search (most small problems): done
            self.info = {"timed_out": False, "proven_optimal": not self.prefix_test, "nodes": int(nodes),
                         "dive_pairings": None if dive_k < 0 else int(dive_k),
                         "history": history}
            return out
        ic, candidates = gate_mask(problem, self.confidence)
        lms = np.flatnonzero(out >= 0)
        best = Incumbent.resumed(out[lms], lms, nodes, history)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap, gate)
        feats, lms, self.info = later_steps(args, candidates, best, timed_out, int(budget[len(candidates)]),
                                            bool(self.prefix_test), lambda *a: self._restarts(problem, *a))
        self.info["dive_pairings"] = int(dive_k)
        out[:] = -1
        out[lms] = feats
        return out

    def warm_up(self, problem: Problem) -> None:
        """``associate``, then every anytime step a tiny problem skips, and the restarts' kernels."""
        self.associate(problem)
        ic = individually_compatible(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        anytime_jcbb(args, 10_000, restarts=lambda *a: self._restarts(problem, *a), quick_nodes=0)
        RJC(confidence=self.confidence).warm_up(problem)

    def _restarts(self, problem: Problem, budget: int, args: tuple, candidates: np.ndarray) -> list[tuple]:
        """Step 2's last starts, each ``(features, landmarks, NIS, nodes)``: the assignment dive and
        seeded RANSAC restarts (RJC's: exact search on 4-feature samples, then a jointly compatible
        completion), as many as the budget has room for."""
        found = []
        if budget >= len(candidates):
            found.append(self._assignment_dive(problem, args, candidates))
            budget -= len(candidates)
        if budget < problem.m:
            return found
        rjc = self.__dict__.get("_rjc")
        if rjc is None or rjc.confidence != self.confidence:
            rjc = self.__dict__["_rjc"] = RJC(confidence=self.confidence)   # built (and checked) once per call's confidence
        rjc.max_iterations = budget // problem.m                             # an int >= 1, as its field demands
        answer = rjc.associate(problem)
        lms = np.flatnonzero(answer >= 0)
        nodes = rjc.info["nodes"] + rjc.info["iterations"] * problem.m
        return [*found, (answer[lms], lms, rjc.info["nis"], nodes)]

    def _assignment_dive(self, problem: Problem, args: tuple, candidates: np.ndarray) -> tuple:
        """A classic dive guided by the optimal assignment (``LSA``'s, on the individual
        log-likelihoods): each assigned landmark may take only its feature, surest pair first;
        ``(features, landmarks, NIS, nodes)``. The assignment sees every pairing at once, where a
        dive commits one at a time."""
        assigned = LSA(confidence=self.confidence).associate(problem)
        feats, lms, nis, _ = gated_pairs(problem, self.confidence)
        pair_nis = np.full(problem.n, np.inf)
        chosen = assigned[lms] == feats
        pair_nis[lms[chosen]] = nis[chosen]
        ic = args[0].copy()
        paired = np.flatnonzero(assigned >= 0)
        ic[:, paired] = False
        ic[assigned[paired], paired] = True
        order = candidates[np.argsort(pair_nis[candidates], kind="stable")]
        feats, lms, nis, _ = classic_dive(ic, *args[1:], order, False)
        return feats, lms, nis, len(candidates)
