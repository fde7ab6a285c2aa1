"""The associator interface: a dataclass of parameters with one method, ``associate``."""

from __future__ import annotations

from dataclasses import dataclass, fields
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

    @classmethod
    def parameters(cls) -> dict[str, object]:
        """Parameter names and defaults."""
        return {f.name: f.default for f in fields(cls)}

    @staticmethod
    def empty(problem: Problem) -> np.ndarray:
        return np.full(problem.n, NO_MATCH, dtype=np.int64)


def greedy_one_to_one(cost: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Greedy matching: repeatedly take the cheapest allowed (feature, landmark) pair whose
    feature and landmark are both still free. ``cost`` and ``allowed`` are (m, n)."""
    m, n = cost.shape
    out = np.full(n, NO_MATCH, dtype=np.int64)
    fi, lj = np.nonzero(allowed)
    order = np.lexsort((fi, lj, cost[fi, lj]))  # ties broken by landmark, then feature index
    used = np.zeros(m, bool)
    for k in order:
        i, j = fi[k], lj[k]
        if out[j] == NO_MATCH and not used[i]:
            out[j] = i
            used[i] = True
    return out
