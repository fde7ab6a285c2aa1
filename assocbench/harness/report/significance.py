"""Whether methods ranked over many blocks differ by more than chance: the Friedman test in Iman and
Davenport's F form, then the Nemenyi critical difference (Demšar, JMLR 7:1-30, 2006, §3.2.2). With k
methods ranked in each of N blocks (1 best, ties sharing places) and R_j the mean rank of method j:

    χ²_F = 12 N / (k (k + 1)) · (Σ_j R_j² − k (k + 1)² / 4)
    F_F  = (N − 1) χ²_F / (N (k − 1) − χ²_F),   F-distributed with k − 1 and (k − 1)(N − 1) dof
    CD   = q_α √(k (k + 1) / (6 N)),   q_α = studentized range quantile(1 − α; k, ∞) / √2

If F_F's p-value is below α, two methods differ when their mean ranks differ by CD or more;
otherwise none does. No tie correction (Demšar's statistics), so ties only make the test more
cautious."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

ALPHA = 0.05


@dataclass(frozen=True)
class RankTest:
    """The test of ``mean_rank`` over ``blocks``: ``chi2`` (χ²_F), ``f`` (F_F), ``p`` (NaN with one
    method or block) and ``cd`` at ``alpha``."""

    methods: tuple[str, ...]
    mean_rank: np.ndarray
    blocks: int
    chi2: float
    f: float
    p: float
    cd: float
    alpha: float = ALPHA

    @property
    def rejects(self) -> bool:
        """Whether the Friedman test finds the ranks unequal at ``alpha``."""
        return bool(self.p < self.alpha)

    def differ(self, i: int, j: int) -> bool:
        """Whether methods ``i`` and ``j`` differ significantly: the test rejects, and their mean
        ranks are at least CD apart."""
        return self.rejects and abs(self.mean_rank[i] - self.mean_rank[j]) >= self.cd

    def places(self) -> np.ndarray:
        """Each method's place: 1 + the methods significantly better, so methods no test tells apart
        share a place (all 1st when the test does not reject)."""
        k = len(self.methods)
        return np.array([1 + sum(self.differ(i, j) and self.mean_rank[j] < self.mean_rank[i] for j in range(k))
                         for i in range(k)])

    def cliques(self) -> list[tuple[int, ...]]:
        """The maximal runs of methods by mean rank that do not differ pairwise (a diagram's bars),
        as index tuples of 2 or more."""
        order = [int(i) for i in np.argsort(self.mean_rank, kind="stable")]
        runs: list[tuple[int, ...]] = []
        for a in range(len(order)):
            b = a
            while b + 1 < len(order) and not self.differ(order[a], order[b + 1]):
                b += 1
            if b > a and not (runs and order[b] == runs[-1][-1]):   # not inside the run before it
                runs.append(tuple(order[a:b + 1]))
        return runs


def block_ranks(values: np.ndarray) -> np.ndarray:
    """Ranks (1 best) of each row of ``values`` (blocks × methods, lower better), ties sharing their
    mean place; NaN and +inf last, tied."""
    keyed = np.where(np.isfinite(values), values, np.inf)
    return stats.rankdata(keyed, method="average", axis=1)


def friedman_nemenyi(ranks: np.ndarray, methods: tuple[str, ...], alpha: float = ALPHA) -> RankTest:
    """The Friedman / Iman-Davenport test and Nemenyi CD of ``ranks`` (blocks × methods, each row
    the ranks 1..k of one block)."""
    n, k = ranks.shape
    mean = ranks.mean(axis=0) if n else np.full(k, np.nan)
    if n < 2 or k < 2:
        return RankTest(tuple(methods), mean, n, math.nan, math.nan, math.nan, math.nan, alpha)
    chi2 = 12 * n / (k * (k + 1)) * (float(np.sum(mean ** 2)) - k * (k + 1) ** 2 / 4)
    chi2 = max(chi2, 0.0)   # rounding of a table of ties
    rest = n * (k - 1) - chi2
    f = math.inf if rest <= 1e-12 else (n - 1) * chi2 / rest   # every block ranks the methods alike: p = 0
    p = float(stats.f.sf(f, k - 1, (k - 1) * (n - 1)))
    q = float(stats.studentized_range.ppf(1 - alpha, k, np.inf)) / math.sqrt(2)
    cd = q * math.sqrt(k * (k + 1) / (6 * n))
    return RankTest(tuple(methods), mean, n, chi2, f, p, cd, alpha)
