"""The learned associator: boosted trees score each gated pair's log-odds of being true, then
one assignment maximises the summed log-odds against a validated no-match cost."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import linear_sum_assignment

from ...association.problem import NO_MATCH, Problem
from ...errors import UserError
from ..base import Associator
from .features import pair_features
from .forest import Forest, check_track, load_forest, shipped_forests

FORBIDDEN = 1e12   # finite stand-in for +inf so the assignment is always feasible


@lru_cache(maxsize=1)
def _shipped() -> dict[str, Forest]:
    return shipped_forests()


def _signature(problem: Problem) -> tuple:
    return problem.d, problem.angular


@dataclass
class Learned(Associator):
    """Gradient-boosted trees on per-pair features (``features.FEATURES``: NIS, log det S, ranks and
    gaps in the pair's row and column, gate counts, NIS after removing the mutual-best pairs' median
    innovation) give each gated pair a log-odds ``f_ij``; the association solves

        max Σ_(i,j)∈A f_ij + (n - |A|)·τ   over one-to-one A (``linear_sum_assignment``),

    so a landmark is paired only when its log-odds beats the no-match cost ``τ`` (validated on
    held-out frames, stored in the model).

    model: path of a model JSON from ``assocbench train``; empty: the model shipped for the
        problem's track, found by its dimension and angular dims.
    """

    name = "learned"
    summary = "gradient-boosted trees on per-pair features, assignment on log-odds with a learned no-match cost"
    model: str = ""

    def __post_init__(self) -> None:
        super().__post_init__()
        self._forest = load_forest(self.model) if self.model else None

    @classmethod
    def check_track(cls, track: str, params: dict) -> None:
        """Refuse, before a run, a model of another track, or a track with no shipped model."""
        if params.get("model"):
            check_track(load_forest(params["model"]), track, params["model"])
        elif track not in _shipped():
            raise UserError(f"method learned has no shipped model for the {track} track (only for "
                            f"{', '.join(_shipped())}): train one (`assocbench export`, `assocbench train`) and "
                            "pass --set params.model=PATH")

    def forest_for(self, problem: Problem) -> Forest:
        """The user's model, or the shipped model whose problems look like ``problem``."""
        if self._forest is not None:
            forest = self._forest
        else:
            found = [f for f in _shipped().values() if f.signature == _signature(problem)]
            if not found:
                raise ValueError(f"no shipped learned model for problems of dimension {problem.d} with angular "
                                 f"dims {problem.angular}: pass --set params.model=PATH")
            forest = found[0]
        if forest.signature != _signature(problem):
            raise ValueError(f"the model's problems have (d, angular) {forest.signature}, this one "
                             f"{_signature(problem)}: it was trained on another track")
        return forest

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        forest = self.forest_for(problem)
        feats, lms, X = pair_features(problem)
        return assign_log_odds(feats, lms, forest.log_odds(X), forest.no_match, problem.m, problem.n)


def assign_log_odds(feats: np.ndarray, lms: np.ndarray, log_odds: np.ndarray, no_match: float,
                    m: int, n: int) -> np.ndarray:
    """``max Σ f_ij + (n - |A|)·τ``: costs ``-f_ij`` against a private dummy column of cost ``-τ``
    per landmark; pairs not listed are forbidden. Returns (n,) features, -1 for none."""
    out = np.full(n, NO_MATCH, dtype=np.int64)
    if len(feats) == 0:
        return out
    rows_used = np.unique(lms)   # landmarks with no gated pair stay unassociated: a smaller problem
    local = np.searchsorted(rows_used, lms)
    k = len(rows_used)
    cost = np.full((k, m + k), FORBIDDEN)
    cost[local, feats] = -log_odds
    cost[np.arange(k), m + np.arange(k)] = -no_match
    rows, cols = linear_sum_assignment(cost)
    real = (cols < m) & (cost[rows, cols] < FORBIDDEN)
    out[rows_used[rows[real]]] = cols[real]
    return out
