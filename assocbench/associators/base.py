"""The associator interface: a dataclass of parameters with one method, ``associate``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..association.problem import NO_MATCH, Problem


@dataclass
class Associator:
    """Base class. Subclasses are dataclasses whose fields are their parameters (with defaults).

    ``associate(problem)`` returns an (n,) int array: the feature paired with each candidate
    landmark, or -1. It may set ``self.info`` (a dict of diagnostics, e.g. ``timed_out``).
    """

    name: ClassVar[str] = "base"
    summary: ClassVar[str] = ""

    def __post_init__(self) -> None:
        self.info: dict = {}

    def associate(self, problem: Problem) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    @staticmethod
    def empty(problem: Problem) -> np.ndarray:
        return np.full(problem.n, NO_MATCH, dtype=np.int64)


def greedy_one_to_one(cost: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Greedy matching: take allowed (feature, landmark) pairs cheapest first, each feature and
    landmark at most once. ``cost`` and ``allowed`` are (m, n).

    Done in rounds: a pair that is the cheapest of both its row and its column is taken by the
    greedy whatever else happens (every pair it excludes costs at least as much), so all such
    mutual-best pairs are taken at once, their rows and columns closed, and the rest redone.
    """
    m, n = cost.shape
    out = np.full(n, NO_MATCH, dtype=np.int64)
    c = np.where(allowed, cost, np.inf)
    while np.isfinite(c).any():
        best_feature = c.argmin(axis=0)                         # per landmark
        best_landmark = c.argmin(axis=1)                        # per feature
        lms = np.flatnonzero(np.isfinite(c[best_feature, np.arange(n)]))
        mutual = lms[best_landmark[best_feature[lms]] == lms]
        out[mutual] = best_feature[mutual]
        c[best_feature[mutual], :] = np.inf
        c[:, mutual] = np.inf
    return out
