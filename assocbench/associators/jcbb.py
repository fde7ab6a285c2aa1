"""JCBB: joint compatibility branch and bound (Neira & Tardós 2001), exact and anytime."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.compatibility import individually_compatible, joint_gates, joint_nis, wrap_mask
from ..association.problem import Problem
from ..validation import in_range
from .base import CONFIDENCE, Associator
from .jcbb_dive import classic_dive, greedy_dive
from .jcbb_search import jcbb_search

REORDERED_DIVES = 3   # each ordered by the previous dive's answer; the class docstring has the measurement
BUDGET_WORK, START_NODES, MAX_BUDGET = 320_000, 12, 20_000   # default_budget
QUICK_NODES = 200     # a first exact search from the classic dive proves most problems up to n ≈ 40 alone;
QUICK_MAX_CANDIDATES = 100   # beyond, it proves none (0 of 20 at n = 160) and costs ~5 ms there


@dataclass
class JCBB(Associator):
    """Largest jointly compatible hypothesis, ties broken by lower joint NIS.

    Pairs must pass the individual gate ``χ²_d(c)``; landmarks without an individually
    compatible partner leave the search. Anytime, in three steps, each starting from the best
    hypothesis so far (the incumbent):

    1. **The classic first dive** (``jcbb_dive.classic_dive``): landmarks in index order, each
       takes the pairing with the smallest joint NIS increase that passes the prefix test, or
       none. Always run in full, so the answer is never worse than classic JCBB's first dive.
       Then, up to ``QUICK_MAX_CANDIDATES``, a short exact search from it (``QUICK_NODES``): it
       proves most problems up to n ≈ 40 alone (all 20 at n = 40), which then skip step 2
       (n = 10: 0.08 ms, not 0.66).
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
         no lower than the best NIS.

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
        shrinks as the candidates grow, since a node's cost grows with them.
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
        ic = individually_compatible(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        budget = default_budget(int(ic.any(axis=0).sum())) if self.max_nodes is None else int(self.max_nodes)
        feats, lms, self.info = anytime_jcbb(args, budget, bool(self.prefix_test),
                                             restarts=lambda budget: self._restarts(problem, budget))
        out[lms] = feats
        return out

    def warm_up(self, problem: Problem) -> None:
        """``associate``, then every step of the anytime search, which a tiny problem skips
        (its quick search proves it), and the restarts' own kernels."""
        from .rjc import RJC

        self.associate(problem)
        ic = individually_compatible(problem, self.confidence)
        args = (ic, problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                joint_gates(problem.d, problem.n, self.confidence))
        anytime_jcbb(args, 10_000, restarts=lambda budget: self._restarts(problem, budget), quick=False)
        RJC(confidence=self.confidence).warm_up(problem)

    def _restarts(self, problem: Problem, budget: int) -> tuple[np.ndarray, np.ndarray, float, int] | None:
        """RANSAC restarts at the shallow levels: RJC's hypothesis (exact search on random samples
        of 4 features, then a jointly compatible completion), seeded, with as many iterations as
        ``budget`` has room for at one node per feature a completion visits: (features,
        landmarks, NIS, nodes: its search nodes plus those), or None when not even one fits."""
        from .rjc import RJC

        if budget < problem.m:
            return None
        rjc = RJC(confidence=self.confidence, max_iterations=budget // problem.m)
        answer = rjc.associate(problem)
        lms = np.flatnonzero(answer >= 0)
        nodes = rjc.info["nodes"] + rjc.info["iterations"] * problem.m
        return answer[lms], lms, joint_nis(problem, answer), nodes


def default_budget(candidates: int) -> int:
    """Default node budget for ``candidates`` landmarks with an individually compatible feature:
    ``BUDGET_WORK / candidates``, but room for every start of step 2 at least
    (``START_NODES × candidates``: five dives and about seven RANSAC iterations at one node
    per landmark or feature), and at most ``MAX_BUDGET``. A node's cost grows about linearly
    with the candidates (forward checking, the factor's columns), so this keeps the budget's
    time roughly level: about 2100 nodes at n = 160 (medians 31-48 ms over runs of
    ``benchmarks/jcbb_anytime.py``, within the 50 ms target; 400 000 / n gave 51 ms), 8000 at
    n = 40, 3600 at n = 320 (where fewer left the restarts too few iterations: 2 problems fell
    short of SNN's or RJC's answer). On the camera leaderboard it proves 98 % of the
    corridor/hard frames, where a fixed 2500 proved 6 %."""
    return int(min(MAX_BUDGET, max(START_NODES * candidates, BUDGET_WORK // max(candidates, 1))))


def anytime_jcbb(args: tuple, max_nodes: int, prefix_test: bool = False,
                 restarts=None, quick: bool = True) -> tuple[np.ndarray, np.ndarray, dict]:
    """The steps of ``JCBB`` on the kernels' arguments ``(ic, P, z, zhat, R, wrap, gate)``:
    (features, landmarks of the answer, ``info``). ``restarts(budget)``, when given, returns
    one more jointly compatible hypothesis ``(features, landmarks, NIS, nodes)`` to start from,
    found within about ``budget`` nodes, or None. ``quick=False`` skips the quick search (so
    every step runs: ``JCBB.warm_up``). RJC calls this on its samples' sub-problems (without
    restarts)."""
    candidates = np.flatnonzero(args[0].any(axis=0))
    feats, lms, nis, surest = classic_dive(*args, candidates)
    best = _Incumbent(feats, lms, nis, len(candidates))
    quick_nodes = QUICK_NODES if quick and len(candidates) <= QUICK_MAX_CANDIDATES else 0
    timed_out = best.search(args, min(quick_nodes, max_nodes - best.nodes), prefix_test)
    if timed_out:
        _more_starts(args, candidates, surest, best, max_nodes, restarts)
        timed_out = best.search(args, max_nodes - best.nodes, prefix_test)
    info = {"timed_out": timed_out, "proven_optimal": not (timed_out or prefix_test), "nodes": best.nodes,
            "dive_pairings": best.history[0][1], "history": best.history}
    return best.feats, best.lms, info


def _better(k: int, nis: float, best_k: int, best_nis: float) -> bool:
    return k > best_k or (k == best_k and nis < best_nis)


class _Incumbent:
    """The best hypothesis so far (features, landmarks, NIS), the nodes spent and the history of
    improvements ``(nodes, pairings, NIS)``."""

    def __init__(self, feats: np.ndarray, lms: np.ndarray, nis: float, nodes: int) -> None:
        self.feats, self.lms, self.nis, self.nodes = feats, lms, float(nis), nodes
        self.history = [(nodes, len(lms), float(nis))]

    def offer(self, feats: np.ndarray, lms: np.ndarray, nis: float, nodes: int) -> None:
        """Count ``nodes`` spent finding a hypothesis; keep it if it is better."""
        self.nodes += nodes
        if _better(len(lms), nis, len(self.lms), self.nis):
            self.feats, self.lms, self.nis = feats, lms, float(nis)
            self.history.append((self.nodes, len(lms), float(nis)))

    def search(self, args: tuple, budget: int, prefix_test: bool) -> bool:
        """Branch and bound from the incumbent with ``budget`` nodes; True if it timed out."""
        feats, lms, used, timed_out, h_nodes, h_k, h_nis = jcbb_search(*args, budget, prefix_test, self.feats,
                                                                       self.lms, self.nis)
        self.history += [(self.nodes + int(a), int(b), float(c)) for a, b, c in zip(h_nodes[1:], h_k[1:], h_nis[1:])]
        self.feats, self.lms, self.nis = feats, lms, self.history[-1][2]
        self.nodes += min(int(used), max(budget, 0))
        return bool(timed_out)


def _more_starts(args: tuple, candidates: np.ndarray, surest: np.ndarray, best: _Incumbent, max_nodes: int,
                 restarts) -> None:
    """Step 2: the greedy dive, the reordered dives and the restarts, each while the budget lasts."""
    if best.nodes + len(candidates) <= max_nodes:
        best.offer(*greedy_dive(*args, candidates), len(candidates))
    for _ in range(REORDERED_DIVES):
        if best.nodes + len(candidates) > max_nodes:
            break
        feats, lms, nis, surest = classic_dive(*args, candidates[np.argsort(surest[candidates], kind="stable")])
        best.offer(feats, lms, nis, len(candidates))
    found = restarts(max_nodes - best.nodes) if restarts is not None else None
    if found is not None:
        best.offer(*found)
