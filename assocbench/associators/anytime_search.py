"""The anytime JCBB engine (``JCBB``'s steps, class docstring there): the classic dive, a quick
exact search, more starts while the budget lasts, then branch and bound from the best of them.

Its own module so that both ``jcbb`` (the associator, whose restarts are RJC's hypotheses) and
``rjc`` (whose samples it searches) import it without importing each other's module first.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .jcbb_dive import classic_dive, fail_first_order, greedy_dive
from .jcbb_search import jcbb_search

REORDERED_DIVES = 3   # each ordered by the previous dive's answer; JCBB's docstring has the measurement
FAIL_FIRST_REORDERED = 1   # dives after the fail-first one, ordered by its answer (JCBB's docstring)
BUDGET_WORK, START_NODES, MAX_BUDGET = 320_000, 12, 20_000   # default_budget
QUICK_NODES, QUICK_PER_CANDIDATE, QUICK_SHARE = 200, 30, 3   # quick_budget
QUICK_MAX_CANDIDATES = 100   # beyond, a quick search proves none (0 of 20 at n = 160) and costs ~5 ms there


def default_budget(candidates: int) -> int:
    """Default node budget for ``candidates`` landmarks with an individually compatible feature:
    the quick search's nodes (``quick_budget``) on top of the budget of the later steps,
    ``BUDGET_WORK / candidates``, but room for every start of step 2 at least
    (``START_NODES × candidates``: five dives and about seven RANSAC iterations at one node
    per landmark or feature), and at most ``MAX_BUDGET``. A node's cost grows about linearly
    with the candidates (forward checking, the factor's columns), so this keeps the budget's
    time roughly level: about 2100 nodes at n = 160 (medians 31-48 ms over runs of
    ``benchmarks/jcbb_anytime.py``, within the 50 ms target; 400 000 / n gave 51 ms), 8000 at
    n = 40, 3600 at n = 320 (where fewer left the restarts too few iterations: 2 problems fell
    short of SNN's or RJC's answer). On the camera leaderboard it proves 98 % of the
    corridor/hard frames, where a fixed 2500 proved 6 %. A problem the quick search cannot
    prove so keeps the whole budget of the later steps."""
    return sum(default_budgets(candidates))


def default_budgets(candidates: int) -> tuple[int, int]:
    """(nodes of the later steps, nodes of the quick search): ``default_budget`` is their sum."""
    later = int(min(MAX_BUDGET, max(START_NODES * candidates, BUDGET_WORK // max(candidates, 1))))
    return later, quick_budget(candidates, later)


@lru_cache(maxsize=1024)
def budget_tables(n: int, max_nodes: int | None) -> tuple[np.ndarray, np.ndarray]:
    """(quick search's nodes, whole budget) for each count 0..n of candidate landmarks, as
    ``anytime_jcbb`` reckons them: ``default_budgets`` when ``max_nodes`` is None, else
    ``max_nodes`` with ``quick_budget``'s share of it. Read-only, one pair per (n, max_nodes)."""
    counts = range(n + 1)
    if max_nodes is None:
        later, quick = (np.array(col, np.int64) for col in zip(*(default_budgets(c) for c in counts)))
        total = later + quick
    else:
        quick = np.array([quick_budget(c, max_nodes) for c in counts], np.int64)
        total = np.full(n + 1, max_nodes, np.int64)
    quick.flags.writeable = total.flags.writeable = False
    return quick, total


def quick_budget(candidates: int, room: int) -> int:
    """Nodes of the quick exact search from the classic dive: ``QUICK_PER_CANDIDATE`` per candidate
    (at least ``QUICK_NODES``) but at most ``room / QUICK_SHARE``; none past
    ``QUICK_MAX_CANDIDATES`` candidates. On 40 range-bearing problems at n = 40 (about 35
    candidates) the plain search from the classic dive proves every one within 1400 nodes, most
    within 200; the restarts cost more than that search needed (up to several times its time),
    so the quick search gets about a thousand nodes there. A problem it cannot prove wastes
    them (at n = 80 about half, where the restarts' better incumbent then saves more)."""
    if candidates > QUICK_MAX_CANDIDATES:
        return 0
    return int(min(max(QUICK_NODES, QUICK_PER_CANDIDATE * candidates), room // QUICK_SHARE))


def anytime_jcbb(args: tuple, max_nodes: int, prefix_test: bool = False, restarts=None,
                 quick_nodes: int | None = None, candidates: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, dict]:
    """The steps of ``JCBB`` on the kernels' arguments ``(ic, P, z, zhat, R, wrap, gate)``:
    (features, landmarks of the answer, ``info``). ``restarts(budget, args, candidates)``, when
    given, returns more jointly compatible hypotheses ``(features, landmarks, NIS, nodes)`` to
    start from, found within about ``budget`` nodes (possibly none). ``quick_nodes``: the quick search's nodes,
    charged to ``max_nodes`` (None: ``quick_budget(candidates, max_nodes)``; 0 skips it, so every
    step runs: ``JCBB.warm_up``). ``candidates``: the landmarks with an individually compatible
    feature, ascending, when the caller has them (``gate_mask``). RJC calls this on its samples'
    sub-problems (without restarts)."""
    if candidates is None:
        candidates = np.flatnonzero(args[0].any(axis=0))
    if quick_nodes is None:
        quick_nodes = quick_budget(len(candidates), max_nodes)
    # unranked when a quick search follows: a problem it proves never needs the ranking
    feats, lms, nis, surest = classic_dive(*args, candidates, quick_nodes == 0)
    best = Incumbent(feats, lms, nis, len(candidates))
    timed_out = best.search(args, min(quick_nodes, max_nodes - best.nodes), prefix_test)
    return later_steps(args, candidates, best, timed_out, max_nodes, prefix_test, restarts,
                       None if quick_nodes else surest)


def later_steps(args: tuple, candidates: np.ndarray, best: Incumbent, timed_out: bool, max_nodes: int,
                prefix_test: bool, restarts=None, surest: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Steps 2 and 3 after the quick search left ``best`` (``timed_out``: it did not prove it):
    more starts, then branch and bound with the nodes left; (features, landmarks, ``info``) as
    ``anytime_jcbb``. ``surest``: the first dive's ranking, when it was computed."""
    if timed_out:
        if surest is None:      # the ranking of the first dive, again (the same hypothesis): uncounted
            surest = classic_dive(*args, candidates)[3]
        _more_starts(args, candidates, surest, best, max_nodes, restarts)
        timed_out = best.search(args, max_nodes - best.nodes, prefix_test)
    info = {"timed_out": timed_out, "proven_optimal": not (timed_out or prefix_test), "nodes": best.nodes,
            "dive_pairings": best.history[0][1], "history": best.history}
    return best.feats, best.lms, info


def _better(k: int, nis: float, best_k: int, best_nis: float) -> bool:
    return k > best_k or (k == best_k and nis < best_nis)


class Incumbent:
    """The best hypothesis so far (features, landmarks, NIS), the nodes spent and the history of
    improvements ``(nodes, pairings, NIS)``."""

    def __init__(self, feats: np.ndarray, lms: np.ndarray, nis: float, nodes: int) -> None:
        self.feats, self.lms, self.nis, self.nodes = feats, lms, float(nis), nodes
        self.history = [(nodes, len(lms), float(nis))]

    @classmethod
    def resumed(cls, feats: np.ndarray, lms: np.ndarray, nodes: int, history: list[tuple]) -> Incumbent:
        """The incumbent a compiled step left (``jcbb_quick.quick_jcbb_into``): its hypothesis, the
        nodes spent and its history, a list of ``(nodes, pairings, NIS)``."""
        best = cls(feats, lms, float(history[-1][2]), int(nodes))
        best.history = list(history)
        return best

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
        self.history += [(self.nodes + a, b, c) for a, b, c in zip(h_nodes[1:].tolist(), h_k[1:].tolist(),
                                                                   h_nis[1:].tolist())]
        self.feats, self.lms, self.nis = feats, lms, self.history[-1][2]
        self.nodes += min(int(used), max(budget, 0))
        return bool(timed_out)


def _more_starts(args: tuple, candidates: np.ndarray, surest: np.ndarray, best: Incumbent, max_nodes: int,
                 restarts) -> None:
    """Step 2: the greedy dive, the reordered dives, the fail-first dive and one reordered by its
    answer, then the restarts, each while the budget lasts."""
    if best.nodes + len(candidates) <= max_nodes:
        best.offer(*greedy_dive(*args, candidates), len(candidates))
    surest = _reordered_dives(args, candidates, surest, best, max_nodes, REORDERED_DIVES)
    if best.nodes + len(candidates) <= max_nodes:
        order = fail_first_order(*args[:6], candidates)
        feats, lms, nis, surest = classic_dive(*args, order)
        best.offer(feats, lms, nis, len(candidates))
        _reordered_dives(args, candidates, surest, best, max_nodes, FAIL_FIRST_REORDERED)
    for found in (restarts(max_nodes - best.nodes, args, candidates) if restarts is not None else ()):
        best.offer(*found)


def _reordered_dives(args: tuple, candidates: np.ndarray, surest: np.ndarray, best: Incumbent, max_nodes: int,
                     count: int) -> np.ndarray:
    """Up to ``count`` classic dives, each in the order of the previous one's ranking ``surest``
    (surest pairing first), while the budget lasts; returns the last ranking."""
    for _ in range(count):
        if best.nodes + len(candidates) > max_nodes:
            break
        feats, lms, nis, surest = classic_dive(*args, candidates[np.argsort(surest[candidates], kind="stable")])
        best.offer(feats, lms, nis, len(candidates))
    return surest
