"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and anytime."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import gate_mask, individually_compatible, joint_gates, wrap_mask
from ..association.problem import Problem
from ..validation import in_range
from .anytime_search import anytime_jcbb, default_budget, default_budgets
from .base import CONFIDENCE, Associator
from .rjc import RJC

__all__ = ["JCBB", "anytime_jcbb", "default_budget"]


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Pairs must pass the individual gate ``χ²_d(c)``; landmarks without an individually
    compatible partner leave the search. Anytime, in three steps, each starting from the best
    hypothesis so far (the incumbent):

    1. **The classic first dive** (``jcbb_dive.classic_dive``): landmarks in index order, each
       takes the pairing with the smallest joint NIS increase that passes the prefix test, or
       none. Always run in full, so the answer is never worse than classic JCBB's first dive.
       Then, up to ``QUICK_MAX_CANDIDATES`` candidates, a quick exact search from it (about 30
       nodes per candidate, ``anytime_search.quick_budget``): it proves most problems up to
       n ≈ 40 alone (all 40 measured there; about half at n = 80), as cheaply as a plain exact
       search would, and those skip step 2, whose restarts cost more than that search needs
       there. The search proves at its root a problem whose individually compatible pairs form
       a matching all in the dive's answer (most problems at n = 10).
    2. **More starts**, each kept if it beats the incumbent: a global greedy dive (of all free
       pairings, the smallest NIS increase that passes the prefix test, until none does;
       ``jcbb_dive.greedy_dive``); ``REORDERED_DIVES`` classic dives, each with the landmarks
       ordered by how sure their best pairing is given the previous dive's answer (smallest
       ``NIS(H + p) - NIS(H)``, which each dive computes at its end); and restarts at the
       shallow levels: RJC's RANSAC (an exact search on random samples of 4 features, then a
       jointly compatible completion; seeded, so reproducible). A wrong early pairing pins the
       pose wrongly and starves the rest of a dive; once a dive has roughly placed the pose,
       the sure pairings go first, and a clean sample fixes the shallow levels outright.
       Measured on 20 range-bearing problems per n = 40-320 (``benchmarks/jcbb_anytime.py``),
       counting problems where some known jointly compatible hypothesis (the true pairings, or
       another method's answer) has more pairings: reordered dives that stop at the first that
       does not improve left 3 at n = 320; chaining 8 left 1 (SNN's 256 against 253), which the
       greedy dive closed; RJC's answers (merged later) then beat it by one pairing on 4
       problems at n = 160-320, which the restarts closed (so JCBB is never below RJC with the
       same seed, by construction). Three reordered dives with the restarts lose nothing
       against eight and keep n = 160 within 50 ms (medians 30-48 ms over runs of the benchmarks).
    3. **Branch and bound** (compiled, ``jcbb_search``) from the incumbent with the remaining
       node budget. Each node takes the remaining landmark with the fewest feasible features
       (ties: the smallest least NIS increase) and tries, in order, the pairings that keep the
       hypothesis jointly compatible (smallest NIS increase first), leaving it unassociated,
       and the pairings that break the joint test for now (a later, larger hypothesis may pass
       its looser gate). The joint factor grows incrementally (``compatibility.append_rows``) and
       keeps every landmark's conditional moments per hypothesis size, so each node evaluates
       all remaining pairings against it (forward checking). With ``k`` pairings, NIS ``ν`` and
       bound ``b`` on further pairings:

       * a pairing with ``ν + Δν > χ²_{d(k+b)}(c)`` can never complete a jointly compatible
         hypothesis (NIS never decreases as pairings are added), so it leaves the subtree;
       * ``b`` is the maximum matching of the feasible pairings, lowered while
         ``ν + δ_b > χ²_{d(k+b)}(c)``, where ``δ_b`` is the b-th smallest least increment per
         landmark (and per feature);
       * a node is cut when ``k + b`` is below the best count, or equal to it while ``ν + δ_b`` is
         no lower than the best NIS; the test is repeated before each further child, against
         the incumbent its earlier children may have improved, and "unassociated" is skipped
         when the landmarks left in play cannot reach the best count.

    A hypothesis counts when its own NIS passes ``χ²_{dk}(c)``, so a search that ends within its
    budget returns exactly the hypothesis of an exhaustive search (``info["proven_optimal"]``).
    ``prefix_test=True`` also demands that every partial hypothesis of the search pass its own
    test, as in the original paper (smaller tree; it can miss a hypothesis whose prefix fails
    the tighter gate, so its answers are never called proven optimal).

    Limited discrepancy search was measured as the budget's third step and lost to plain depth
    first from the reordered incumbent: re-entering the shallow nodes, the costliest ones, made
    it 2-4× slower per node with no more pairings at n = 40-320.

    confidence: individual and joint gate ``c``.
    max_nodes: node budget (a dive counts one node per landmark it visits, the restarts their
        search nodes and one per feature each completion visits). The classic dive always runs;
        every later step starts only if the budget has room for it (the restarts run as many
        RANSAC iterations as it has room for; a step started is finished, so the total can
        exceed the budget by the restarts' small sample searches); when spent, the incumbent is
        returned and ``info["timed_out"]`` is True. None (the default): ``default_budget``, which
        shrinks as the candidates grow, since a node's cost grows with them, and holds the quick
        search's nodes on top (so a problem it cannot prove keeps the whole budget of step 2-3).
    prefix_test: apply the joint test to every partial hypothesis (classic JCBB).

    ``info``: ``timed_out``, ``proven_optimal``, ``nodes`` (dives, restarts and search),
    ``dive_pairings`` (the classic dive's count), ``history`` (one ``(nodes, pairings, NIS)``
    per improvement of the incumbent, nodes counted so far, the classic dive first: the
    anytime curve).
    """

    name = "jcbb"
    summary = "joint compatibility branch and bound: most jointly compatible pairings, then lowest NIS"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    max_nodes: int | None = field(default=None, metadata=in_range(1))
    prefix_test: bool = False

    def associate(self, problem: Problem) -> np.ndarray:
        out = self.empty(problem)
        self.info = {"timed_out": False, "proven_optimal": True, "nodes": 0, "dive_pairings": 0, "history": []}
        if problem.m == 0 or problem.n == 0:
            return out
        ic, candidates = gate_mask(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        if self.max_nodes is None:
            later, quick = default_budgets(len(candidates))
            budget = later + quick
        else:
            budget, quick = int(self.max_nodes), None
        feats, lms, self.info = anytime_jcbb(args, budget, bool(self.prefix_test),
                                             restarts=lambda budget: self._restarts(problem, budget),
                                             quick_nodes=quick, candidates=candidates)
        out[lms] = feats
        return out

    def warm_up(self, problem: Problem) -> None:
        """``associate``, then every step of the anytime search, which a tiny problem skips
        (its quick search proves it), and the restarts' own kernels."""
        self.associate(problem)
        ic = individually_compatible(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        anytime_jcbb(args, 10_000, restarts=lambda budget: self._restarts(problem, budget), quick_nodes=0)
        RJC(confidence=self.confidence).warm_up(problem)

    def _restarts(self, problem: Problem, budget: int) -> tuple[np.ndarray, np.ndarray, float, int] | None:
        """RANSAC restarts at the shallow levels: RJC's hypothesis (exact search on random samples
        of 4 features, then a jointly compatible completion), seeded, with as many iterations as
        ``budget`` has room for at one node per feature a completion visits: (features,
        landmarks, NIS, nodes: its search nodes plus those), or None when not even one fits."""
        if budget < problem.m:
            return None
        rjc = self.__dict__.get("_rjc")
        if rjc is None or rjc.confidence != self.confidence:
            rjc = self.__dict__["_rjc"] = RJC(confidence=self.confidence)   # built (and checked) once: ~1 ms
        rjc.max_iterations = budget // problem.m                             # an int >= 1, as its field demands
        answer = rjc.associate(problem)
        lms = np.flatnonzero(answer >= 0)
        nodes = rjc.info["nodes"] + rjc.info["iterations"] * problem.m
        return answer[lms], lms, rjc.info["nis"], nodes
