"""JPDA: joint probabilistic data association (Fortmann, Bar-Shalom & Scheffe 1983), a soft
associator: marginal association probabilities, exact per cluster by enumeration, loopy belief
propagation (Williams & Lau 2014) past a size limit.

Landmarks ``j``, features ``i``; a pair is gated when ``NIS_ij <= χ²_d(c)``. A joint event ``θ``
pairs each landmark with at most one gated feature and each feature with at most one landmark; the
parametric model (Bar-Shalom & Li 1995) gives

    P(θ) ∝ Π_{(i,j)∈θ} P_D N_ij / λ · Π_{j undetected in θ} (1 - P_D P_G),

with ``N_ij = N(z_i; zhat_j, P_jj + R_i)``, ``λ`` the clutter density, ``P_G = c``. The marginals
are ``β_ji = Σ_{θ∋(i,j)} P(θ)`` and ``β_j∅ = 1 - Σ_i β_ji``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..association.compatibility import gated_pairs, log_gaussian
from ..association.problem import Problem
from ..validation import in_range
from .base import CONFIDENCE, Associator, greedy_one_to_one
from .jpda_kernels import jpda_marginals

BP_TOL = 1e-10        # BP stops when no message ν (in (0, 1]) moves more than this in a sweep
BP_MAX_SWEEPS = 2000  # and in any case after this many (range-bearing clusters up to n = 320 needed at most 1111)


@dataclass
class JPDA(Associator):
    """Joint probabilistic data association: the marginal probability ``β_ji`` that landmark ``j``
    produced feature ``i`` (``β_j∅``: undetected), then a hard association. Each landmark's own
    block ``P_jj`` is used, cross-covariances ignored (so, unlike JCBB, no common pose error is
    exploited).

    Events factor over the gating graph's clusters. A cluster with at most ``max_events`` events
    (``events_lower_bound``, ``count_events``) is enumerated exactly, depth first; a larger one gets
    loopy belief propagation (Williams & Lau 2014: linear per sweep, exact on a tree; overconfident
    on loops, though its hard answers almost always agree: ``benchmarks/jpda_scale.py``). Hard
    answer: ``j`` may take ``i`` when ``β_ji > β_j∅``, highest ``β`` first, one-to-one
    (``greedy_one_to_one``).

    ``info``: ``exact``, ``approximate_clusters``, ``events``, ``clusters``, ``largest_cluster``,
    ``bp_sweeps``, ``marginals``.

    p_detect: ``P_D``, the probability a candidate yields a feature (0.8-0.95 score alike).
    confidence: the gate ``χ²_d(c)``, also ``P_G``.
    clutter_density: ``λ``, false features per unit volume; None: ``1 / |Y|``, the ``log|Y|`` the
        surprisal and LSA use.
    max_events: the most events an enumerated cluster may have; the default keeps n = 10 within its
        time limit.
    """

    name = "jpda"
    summary = "joint probabilistic data association: marginals (exact per cluster, BP past max_events), then greedy"
    soft = True
    p_detect: float = field(default=0.9, metadata=in_range(0, 1, lo_open=True))
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    clutter_density: float | None = field(default=None, metadata=in_range(0, None, lo_open=True))
    max_events: int = field(default=50_000, metadata=in_range(1))

    def pair_log_weights(self, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
        """(gated, logr), both (m, n): the gate mask and ``log(P_D N_ij / (λ (1 - P_D P_G)))``, a
        pairing's log-weight against its landmark undetected (-inf outside the gate)."""
        feats, lms, nis, logdet = gated_pairs(problem, self.confidence)
        density = 1.0 / problem.volume if self.clutter_density is None else self.clutter_density
        log_ratio = np.log(self.p_detect) - np.log(density) - np.log1p(-self.p_detect * self.confidence)
        gated = np.zeros((problem.m, problem.n), np.bool_)
        logr = np.full((problem.m, problem.n), -np.inf)
        gated[feats, lms] = True
        logr[feats, lms] = log_gaussian(nis, logdet, problem.d) + log_ratio
        return gated, logr

    def marginals(self, problem: Problem) -> np.ndarray:
        """``β`` (n, m + 1), last column ``β_j∅``; sets ``self.info`` (see the class docstring)."""
        gated, logr = self.pair_log_weights(problem)
        beta, events, clusters, approx, largest, sweeps = jpda_marginals(
            np.ascontiguousarray(gated), np.ascontiguousarray(logr), int(self.max_events), BP_TOL, BP_MAX_SWEEPS)
        self.info = {"marginals": beta, "exact": approx == 0, "approximate_clusters": int(approx),
                     "events": int(events), "clusters": int(clusters), "largest_cluster": int(largest),
                     "bp_sweeps": int(sweeps)}
        return beta

    def warm_up(self, problem: Problem) -> None:
        """``associate``, then once with every cluster past the cut-over, so loopy BP compiles too."""
        self.associate(problem)
        replace(self, max_events=1).associate(problem)

    def associate(self, problem: Problem) -> np.ndarray:
        beta = self.marginals(problem)
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        pair = beta[:, :problem.m]
        return greedy_one_to_one(-pair.T, (pair > beta[:, problem.m:]).T)
