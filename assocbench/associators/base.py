"""The associator interface: a dataclass of parameters with one method, ``associate``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from ..association.problem import NO_MATCH, Problem
from ..validation import in_range, validate_fields

CONFIDENCE = in_range(0, 1, lo_open=True, hi_open=True)  # field metadata of a χ² gate's confidence


@dataclass
class Associator:
    """Base class. Subclasses are dataclasses whose fields are their parameters (with defaults).

    ``associate(problem)`` returns an (n,) int array: the feature paired with each candidate
    landmark, or -1; it may set ``self.info`` (diagnostics, e.g. ``timed_out``).

    Parameters are checked when built (``validate_fields``): the type from the annotation, the range
    from metadata (``confidence: float = field(default=0.99, metadata=CONFIDENCE)``); a bad value is
    a one-line ``UserError`` naming ``params.<field>``. A subclass's ``__post_init__`` calls
    ``super().__post_init__()``.

    ``soft``: a soft associator reports marginals in ``info["marginals"]`` (n, m + 1): row ``j``
    holds ``P(j ↔ feature i)`` in column ``i`` and ``P(j unassociated)`` last, each row summing to
    1.
    """

    name: ClassVar[str] = "base"
    summary: ClassVar[str] = ""
    soft: ClassVar[bool] = False

    def __post_init__(self) -> None:
        validate_fields(self, "params")
        self.info: dict = {}

    def associate(self, problem: Problem) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def warm_up(self, problem: Problem) -> None:
        """Load every compiled kernel ``associate`` may use on a tiny ``problem``, so no frame's
        runtime includes a compile. The default calls ``associate`` once; a method whose paths a
        tiny problem skips overrides it."""
        self.associate(problem)

    @staticmethod
    def empty(problem: Problem) -> np.ndarray:
        out = np.empty(problem.n, dtype=np.int64)     # cheaper than np.full
        out.fill(NO_MATCH)
        return out


def greedy_one_to_one(cost: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Greedy matching: allowed (feature, landmark) pairs cheapest first, each feature and landmark
    once; ``cost``, ``allowed`` (m, n). In rounds: a pair cheapest in both its row and column is
    taken whatever else happens, so all such mutual-best pairs are taken at once and the rest redone
    (``_mutual_best_rounds``; ties to the lowest index).
    """
    m, n = cost.shape
    c = np.where(allowed, cost, np.inf).astype(np.float64)
    return _mutual_best_rounds(c, m, n)


def greedy_pairs(feats: np.ndarray, lms: np.ndarray, cost: np.ndarray, m: int, n: int) -> np.ndarray:
    """``greedy_one_to_one`` on a sparse pair list (``feats[t]``, ``lms[t]``, ``cost[t]``, by
    landmark then feature): stable sort, each pair taken while both ends are free; the same matching
    where costs differ, at O(q log q). Returns (n,) features, -1 for none."""
    return sorted_greedy(feats, lms, cost, m, n)


@njit(cache=True)
def sorted_greedy(feats, lms, cost, m, n):
    """``greedy_pairs``, compiled (callable from compiled code)."""
    out = np.full(n, NO_MATCH, np.int64)
    taken = np.zeros(m, np.bool_)
    for t in np.argsort(cost, kind="mergesort"):
        i, j = feats[t], lms[t]
        if out[j] < 0 and not taken[i]:
            out[j] = i
            taken[i] = True
    return out


@njit(cache=True)
def _mutual_best_rounds(c, m, n):
    out = np.full(n, NO_MATCH, np.int64)
    best_feature = np.empty(n, np.int64)
    best_landmark = np.empty(m, np.int64)
    taken = np.empty(n, np.int64)
    while True:
        for j in range(n):                      # cheapest feature of each landmark
            best_feature[j] = np.argmin(c[:, j])
        for i in range(m):                      # cheapest landmark of each feature
            best_landmark[i] = np.argmin(c[i])
        count = 0
        for j in range(n):
            i = best_feature[j]
            if np.isfinite(c[i, j]) and best_landmark[i] == j:
                taken[count] = j
                count += 1
        if count == 0:
            return out
        for t in range(count):                  # close the rows and columns taken this round
            j = taken[t]
            out[j] = best_feature[j]
            c[best_feature[j], :] = np.inf
            c[:, j] = np.inf
