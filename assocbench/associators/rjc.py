"""RJC: randomised joint compatibility (Paz, Guivant, Tardós & Neira, RSS 2007). RANSAC over the
features: JCBB on a sample of ``b`` features (a tree of ``b`` levels whatever the size), then a
one-pass completion; the largest hypothesis is kept. A sample is clean with probability
``P_good^b``, so after

    t = ceil( log(1 - P_success) / log(1 - P_good^b) )

iterations one was clean with probability ``P_success``; ``P_good = max(P_good, k_best / N)`` adapts
``t``. Unlike the paper: the completion keeps the hypothesis jointly compatible (smallest joint NIS
increase, not the nearest neighbour); only features with a compatible landmark are drawn and counted
in ``N``; ties go to the lower joint NIS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..association.compatibility import individually_compatible, joint_gates, wrap_mask
from ..association.problem import Problem
from ..validation import in_range
from .anytime_search import anytime_jcbb
from .base import CONFIDENCE, Associator
from .rjc_kernels import adjacency, complete, make_work


def ransac_iterations(p_fail: float, p_good: float, sample_size: int) -> int:
    """``ceil(log(P_fail) / log(1 - P_good^b))``, at least 1 (huge when ``p_good^b`` underflows; the
    caller caps it)."""
    clean = p_good ** sample_size
    if clean >= 1.0:
        return 1
    if clean <= 0.0:
        return 2**62
    return max(1, math.ceil(math.log(p_fail) / math.log1p(-clean)))


@dataclass
class RJC(Associator):
    """Randomised joint compatibility. Each iteration draws ``b = min(sample_size, N)`` of the ``N``
    features with a compatible landmark (``default_rng(seed)`` made afresh by every call), runs JCBB
    on them (``anytime_search.anytime_jcbb``) and completes it: the other features, fewest
    compatible landmarks first, each take the open landmark with the smallest joint NIS increase
    keeping ``NIS ≤ χ²_{d(k+1)}(c)``. Most pairings win, ties to the lower NIS; a completion that
    cannot win is abandoned; ``N ≤ sample_size`` gives JCBB's answer. Defaults are the paper's
    (``t = 9`` before adapting; ``benchmarks/rjc_scale.py``).

    confidence: individual and joint gates ``χ²_{dk}(c)``.
    sample_size: features per sample ``b``.
    p_fail: acceptable probability that no sample was clean.
    p_good: prior probability that a feature is good (raised to the best hypothesis' share as the
        loop runs).
    iterations: a fixed number of iterations; None adapts ``t``.
    max_iterations: cap on the adaptive count.
    max_nodes: node budget of each sample's JCBB.
    seed: seed of the sampling.

    ``info``: ``iterations``, ``required`` (the adaptive count), ``nodes``, ``timed_out``, ``nis``.
    """

    name = "rjc"
    summary = "randomised joint compatibility: RANSAC over features, JCBB on each sample, joint NN completion"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    sample_size: int = field(default=4, metadata=in_range(1))
    p_fail: float = field(default=0.01, metadata=in_range(0, 1, lo_open=True, hi_open=True))
    p_good: float = field(default=0.8, metadata=in_range(0, 1, lo_open=True))
    iterations: int | None = field(default=None, metadata=in_range(1))
    max_iterations: int = field(default=100, metadata=in_range(1))
    max_nodes: int = field(default=10_000, metadata=in_range(1))
    seed: int = field(default=0, metadata=in_range(0))

    def warm_up(self, problem: Problem) -> None:
        """``associate``, then once with one-feature samples, so the completion compiles too."""
        self.associate(problem)
        replace(self, sample_size=1).associate(problem)

    def associate(self, problem: Problem) -> np.ndarray:
        problem.validate()              # reads P's cross terms (a no-op once checked)
        out = self.empty(problem)
        self.info = {"iterations": 0, "required": 0, "nodes": 0, "timed_out": False, "nis": 0.0}
        if problem.m == 0 or problem.n == 0:
            return out
        ic = individually_compatible(problem, self.confidence)
        start, adj = adjacency(ic)
        counts = np.diff(start)
        gated = np.flatnonzero(counts > 0)
        if gated.size == 0:
            return out
        order = gated[np.argsort(counts[gated], kind="stable")]    # fewest candidates first
        best_i, best_j, nis, nodes, timed_out, ran, required = self._ransac(problem, ic, (start, adj), gated, order)
        out[best_j] = best_i
        self.info = {"iterations": ran, "required": int(required), "nodes": nodes,
                     "timed_out": bool(timed_out or ran < required), "nis": nis}
        return out

    def _ransac(self, problem: Problem, ic: np.ndarray, csr: tuple, gated: np.ndarray, order: np.ndarray) -> tuple:
        """The RANSAC loop: (best features, best landmarks, their joint NIS, JCBB nodes, a JCBB out
        of budget, iterations run, iterations required)."""
        b = min(int(self.sample_size), gated.size)
        adaptive = self.iterations is None and b < gated.size
        if b == gated.size:
            required = 1                                   # the sample is every feature: JCBB
        else:
            required = int(self.iterations) if self.iterations is not None else \
                ransac_iterations(self.p_fail, self.p_good, b)
        cap = self.max_iterations if adaptive else required
        wrap, gate = wrap_mask(problem), joint_gates(problem.d, problem.n, self.confidence)
        work = make_work(problem.n, problem.d)
        pairs = np.empty(problem.n, np.int64), np.empty(problem.n, np.int64)
        in_sample = np.zeros(problem.m, np.bool_)
        rng = np.random.default_rng(self.seed)
        best_k, best_nis, best = 0, np.inf, (np.empty(0, np.int64), np.empty(0, np.int64))
        ran, nodes, timed_out = 0, 0, False
        while ran < min(required, cap):
            sample = np.sort(rng.choice(gated, size=b, replace=False))
            seed_i, seed_j, used, spent = sample_hypothesis(problem, ic, sample, wrap, gate, int(self.max_nodes))
            in_sample[sample] = True
            k, nis = complete(seed_i, seed_j, order, in_sample, *csr, problem.P, problem.z, problem.zhat, problem.R,
                              wrap, gate, best_k, best_nis, work, *pairs)
            in_sample[sample] = False
            ran, nodes, timed_out = ran + 1, nodes + used, timed_out or spent
            if k > best_k or (k == best_k and k > 0 and nis < best_nis):
                best_k, best_nis, best = k, nis, (pairs[0][:k].copy(), pairs[1][:k].copy())
            if adaptive:
                required = ransac_iterations(self.p_fail, max(self.p_good, best_k / gated.size), b)
        return *best, float(best_nis) if best_k else 0.0, nodes, timed_out, ran, required


def sample_hypothesis(problem: Problem, ic: np.ndarray, sample: np.ndarray, wrap: np.ndarray, gate: np.ndarray,
                      max_nodes: int) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """JCBB on the features ``sample`` (ascending) alone: (features, landmarks, nodes, out of
    budget). The sub-problem keeps the landmarks compatible with one of them, in order, so the
    search visits the tree ``anytime_jcbb`` would with the other features' ``ic`` rows cleared; its
    arrays are read-only so JCBB's compiled search serves."""
    lms = np.flatnonzero(ic[sample].any(axis=0))
    rows = (lms[:, None] * problem.d + np.arange(problem.d)).ravel()
    sub = (problem.P[np.ix_(rows, rows)], problem.z[sample], problem.zhat[lms], problem.R[sample])
    for arr in sub:
        arr.flags.writeable = False
    feats, sub_lms, info = anytime_jcbb((ic[np.ix_(sample, lms)], *sub, wrap, gate), max_nodes)
    return sample[feats], lms[sub_lms], info["nodes"], info["timed_out"]
