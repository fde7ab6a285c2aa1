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
    of three (each about 0.3 µs, as much as several search nodes at n = 10)."""
    return (chi2_threshold(d, confidence), joint_gates(d, n, confidence), *budget_tables(n, max_nodes))


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Pairs must pass the individual gate ``χ²_d(c)``; landmarks without an individually
    compatible partner leave the search. Anytime, in three steps, each starting from the best
    hypothesis so far (the incumbent):

    1. **A quick exact search, and the classic first dive** (one compiled call,
       ``jcbb_quick.quick_jcbb``, with the individual gate). Up to ``QUICK_MAX_CANDIDATES``
       candidates the search gets about 30 nodes per candidate (``anytime_search.quick_budget``):
       it proves most problems up to n ≈ 40 alone (all 40 measured there; about half at n = 80),
       and those skip step 2, whose restarts cost more than the search needs there. Where the
       individually compatible pairs form a matching (most problems at n = 10), the classic
       dive runs first and the search proves at its root a dive that took them all; elsewhere
       the plain search from the empty hypothesis runs first (what a proof costs at least: its
       first path is a dive of its own, and the same search from the classic dive's answer
       took the dive's time on top), and a problem it proves costs exactly its nodes. Where it
       runs out (and always past ``QUICK_MAX_CANDIDATES``), **the classic first dive**
       (``jcbb_dive.classic_dive``): landmarks in index order, each takes the pairing with the
       smallest joint NIS increase that passes the prefix test, or none; run in full, so an
       unproven answer is never worse than classic JCBB's first dive.
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
       Before the restarts, two more dives (issue 28): one in fail-first order (fewest
       individually compatible features first, ``jcbb_dive.fail_first_order``) followed by one
       reordered by its answer, and one guided by the optimal assignment (``_assignment_dive``).
       On 100 problems at n = 160 the default budget had left 3 one pairing below a known
       jointly compatible hypothesis (the true pairings on one, LSA's answer on two; 16 times
       the budget closed none of them): these dives close all three, and none of the 100 is
       below any known hypothesis.
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
    ``dive_pairings`` (the classic dive's count; None where the quick search proved the problem
    before any dive), ``history`` (one ``(nodes, pairings, NIS)``
    per improvement of the incumbent, nodes counted so far, the classic dive first: the
    anytime curve).
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
        """``associate``, then every step of the anytime search, which a tiny problem skips
        (its quick search proves it), and the restarts' own kernels."""
        self.associate(problem)
        ic = individually_compatible(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        anytime_jcbb(args, 10_000, restarts=lambda *a: self._restarts(problem, *a), quick_nodes=0)
        RJC(confidence=self.confidence).warm_up(problem)

    def _restarts(self, problem: Problem, budget: int, args: tuple, candidates: np.ndarray) -> list[tuple]:
        """The last starts of step 2, each ``(features, landmarks, NIS, nodes)``: the assignment
        dive (``_assignment_dive``) and RANSAC restarts at the shallow levels, RJC's hypothesis
        (exact search on random samples of 4 features, then a jointly compatible completion),
        seeded, with as many iterations as the budget left has room for at one node per feature
        a completion visits (its nodes: its search nodes plus those); none that does not fit."""
        found = []
        if budget >= len(candidates):
            found.append(self._assignment_dive(problem, args, candidates))
            budget -= len(candidates)
        if budget < problem.m:
            return found
        rjc = self.__dict__.get("_rjc")
        if rjc is None or rjc.confidence != self.confidence:
            rjc = self.__dict__["_rjc"] = RJC(confidence=self.confidence)   # built (and checked) once: ~1 ms
        rjc.max_iterations = budget // problem.m                             # an int >= 1, as its field demands
        answer = rjc.associate(problem)
        lms = np.flatnonzero(answer >= 0)
        nodes = rjc.info["nodes"] + rjc.info["iterations"] * problem.m
        return [*found, (answer[lms], lms, rjc.info["nis"], nodes)]

    def _assignment_dive(self, problem: Problem, args: tuple, candidates: np.ndarray) -> tuple:
        """A classic dive guided by the optimal one-to-one assignment (``LSA``'s, on the individual
        log-likelihoods): each landmark the assignment pairs may take only its assigned feature,
        and the landmarks go in the order of their assigned pair's individual NIS, surest first;
        ``(features, landmarks, NIS, nodes)``, one node per candidate. The assignment sees every
        pairing at once, where a dive commits one landmark at a time."""
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
