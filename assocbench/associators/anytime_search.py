"""The anytime JCBB engine (``JCBB``'s steps, class docstring there), in its own module so both
``jcbb`` and ``rjc`` import it without importing each other.
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
QUICK_MAX_CANDIDATES = 100   # beyond, a quick search almost never proves the problem and only costs time


def default_budget(candidates: int) -> int:
    """Default node budget for ``candidates`` landmarks with a compatible feature: the quick
    search's nodes (``quick_budget``) plus ``BUDGET_WORK / candidates`` for the later steps, at
    least ``START_NODES × candidates`` (room for every start of step 2) and at most ``MAX_BUDGET``.
    A node's cost grows about linearly with the candidates, so this keeps the budget's time roughly
    level across problem sizes (``benchmarks/jcbb_anytime.py``)."""
    return sum(default_budgets(candidates))


def default_budgets(candidates: int) -> tuple[int, int]:
    """(nodes of the later steps, nodes of the quick search): ``default_budget`` is their sum."""
    later = int(min(MAX_BUDGET, max(START_NODES * candidates, BUDGET_WORK // max(candidates, 1))))
    return later, quick_budget(candidates, later)


@lru_cache(maxsize=1024)
def budget_tables(n: int, max_nodes: int | None) -> tuple[np.ndarray, np.ndarray]:
    """(quick search's nodes, whole budget) per count 0..n of candidates: ``default_budgets``, or
    ``max_nodes`` with ``quick_budget``'s share. Read-only, cached."""
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
    """Nodes of the quick exact search: ``QUICK_PER_CANDIDATE`` per candidate (at least
    ``QUICK_NODES``), at most ``room / QUICK_SHARE``; none past ``QUICK_MAX_CANDIDATES``. Enough to
    prove most problems of a few dozen candidates, which then skip the costlier restarts; a problem
    it cannot prove wastes them."""
    if candidates > QUICK_MAX_CANDIDATES:
        return 0
    return int(min(max(QUICK_NODES, QUICK_PER_CANDIDATE * candidates), room // QUICK_SHARE))


def anytime_jcbb(args: tuple, max_nodes: int, prefix_test: bool = False, restarts=None,
                 quick_nodes: int | None = None, candidates: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, dict]:
    """``JCBB``'s steps on the kernels' arguments ``(ic, P, z, zhat, R, wrap, gate)``: (features,
    landmarks, ``info``). ``restarts(budget, args, candidates)`` returns more jointly compatible
    starts ``(features, landmarks, NIS, nodes)``; ``quick_nodes``: the quick search's nodes (None:
    ``quick_budget``; 0 skips it, so every step runs); ``candidates``: the landmarks with a
    compatible feature, when known. RJC calls it on its samples without restarts."""
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
    """Steps 2 and 3 after the quick search left ``best`` unproven: more starts, then branch and
    bound; ``surest``: the first dive's ranking when computed."""
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
        """The incumbent ``jcbb_quick.quick_jcbb_into`` left: hypothesis, nodes and history."""
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
    """Step 2: the greedy, reordered and fail-first dives, then the restarts, while the budget
    lasts."""
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
    """Up to ``count`` classic dives, each ordered by the previous one's ``surest``; returns the
    last ranking."""
    for _ in range(count):
        if best.nodes + len(candidates) > max_nodes:
            break
        feats, lms, nis, surest = classic_dive(*args, candidates[np.argsort(surest[candidates], kind="stable")])
        best.offer(feats, lms, nis, len(candidates))
    return surest
