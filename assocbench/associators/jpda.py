"""JPDA: joint probabilistic data association (Fortmann, Bar-Shalom & Scheffe 1983), a soft
associator: marginal association probabilities, exact per cluster by enumeration, loopy belief
propagation (Williams & Lau 2014) past a size limit.

Landmarks (targets) ``j``, features ``i``. A pair is gated when ``NIS_ij <= χ²_d(c)``
(``compatibility.individually_compatible``). A joint event ``θ`` pairs each landmark with at
most one gated feature and each feature with at most one landmark; the parametric JPDA model
(Fortmann, Bar-Shalom & Scheffe 1983, IEEE J. Oceanic Eng. 8(3); Bar-Shalom & Li,
*Multitarget-Multisensor Tracking: Principles and Techniques*, 1995) gives

    P(θ) ∝ Π_{(i,j)∈θ} P_D N_ij / λ · Π_{j undetected in θ} (1 - P_D P_G),

with ``N_ij = N(z_i; zhat_j, P_jj + R_i)`` (``pairwise_log_likelihood``'s terms, with the gate's NIS),
``λ`` the clutter density, ``P_G = c`` the gate probability. The marginals are
``β_ji = Σ_{θ∋(i,j)} P(θ)`` and ``β_j∅ = 1 - Σ_i β_ji``.
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
    """Joint probabilistic data association: the marginal probability ``β_ji`` that landmark
    ``j`` produced feature ``i`` (``β_j∅``: it went undetected), then a hard association from them.

    Like the tracking literature, JPDA treats the landmarks' predictions as independent: it
    uses each landmark's own block ``P_jj`` and ignores the cross-covariances ``P_jk`` (so,
    unlike JCBB, it cannot exploit a common pose error).

    **Exact, cluster by cluster.** Landmarks and features joined by gated pairs form the
    connected components (clusters) of the gating graph; events factor over clusters, so each
    cluster's events are enumerated on their own, depth first (compiled, log-sum-exp).

    **Cut-over.** A cluster is enumerated when it has at most ``max_events`` joint events: the
    count comes from a cheap lower bound (``events_lower_bound``; above the budget: no count)
    or from a weightless walk of the events that stops at the budget (``count_events``, about a
    tenth of the enumeration's cost per event). A larger cluster is handed to loopy belief
    propagation on the assignment problem (Williams & Lau 2014, "Approximate evaluation of
    marginal association probabilities with belief propagation", IEEE TAES 50(4)): linear per
    sweep in the gated pairs, exact when the cluster's gating graph is a tree. On loops BP
    (the Bethe approximation) is overconfident: it leans to the likelier of competing
    assignments, so single marginals can be off by 0.25 (a 2 x 2 loop, the worst of the small
    problems in tests/test_jpda.py) and up to 0.45 on range-bearing clusters. Its hard answers
    still agree with exact JPDA's (123 of the 124 landmarks of those small problems), and with
    BP forced on every cluster, precision and recall on range-bearing problems (n = 10-160,
    where JPDA is exact or nearly) move by at most 0.002 and true mass rises by at most 0.01
    (benchmarks/jpda_scale.py, row ``jpda-bp``). On range-bearing problems the cut-over first
    happens at n = 160 (3 of 20 problems, 5 clusters); at n = 320 every problem has some.
    ``info``: ``exact`` (every cluster enumerated), ``approximate_clusters``, ``events`` (joint
    events enumerated, summed over the exact clusters), ``clusters``, ``largest_cluster``
    (landmarks), ``bp_sweeps`` (most sweeps of an approximate cluster) and ``marginals``.

    **Hard answer.** Landmark ``j`` may take feature ``i`` when ``β_ji > β_j∅``; among such
    pairs the highest ``β`` is taken first, one-to-one (``greedy_one_to_one`` with cost ``-β``),
    so each landmark gets its most probable feature unless a landmark more sure of it has it.

    p_detect: ``P_D``, the probability a candidate landmark yields a feature. Shipped 0.9: a
        middle value; on the synthetic range-bearing and camera problems (true P_D 0.8) any of
        0.8, 0.9, 0.95 gives the same precision and recall to within 0.01.
    confidence: the gate ``χ²_d(c)``, also ``P_G``. Shipped 0.99 like the other methods.
    clutter_density: ``λ``, false features per unit measurement volume. ``None`` (shipped) uses
        ``1 / |Y|`` (``problem.volume``): one clutter feature expected over the domain, so a
        pairing is weighed against leaving its landmark alone at the same ``log|Y|`` as the
        surprisal and LSA use. On those problems it gave the highest true mass; Bar-Shalom's
        nonparametric ``m / |Y|`` (every feature possibly clutter) lost 0.01-0.1 of it.
    max_events: the most joint events a cluster may have and still be enumerated. Shipped
        50 000: enumeration costs 25-70 ns an event for a 10-landmark cluster
        (benchmarks/jpda_scale.py, calibration), so at most about 3.5 ms: exact JPDA at
        n = 10 stays within 5 ms.
    """

    name = "jpda"
    summary = "joint probabilistic data association: marginals (exact per cluster, BP past max_events), then greedy"
    soft = True
    p_detect: float = field(default=0.9, metadata=in_range(0, 1, lo_open=True))
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    clutter_density: float | None = field(default=None, metadata=in_range(0, None, lo_open=True))
    max_events: int = field(default=50_000, metadata=in_range(1))

    def pair_log_weights(self, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
        """(gated, logr), both (m, n): the gate mask and ``log(P_D N_ij / (λ (1 - P_D P_G)))``,
        the log-weight a pairing adds to an event relative to leaving its landmark undetected
        (-inf outside the gate: never read)."""
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
        """``associate``, then once with every cluster past the cut-over, so that loopy belief
        propagation (which a tiny problem never needs) is compiled too."""
        self.associate(problem)
        replace(self, max_events=1).associate(problem)

    def associate(self, problem: Problem) -> np.ndarray:
        beta = self.marginals(problem)
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        pair = beta[:, :problem.m]
        return greedy_one_to_one(-pair.T, (pair > beta[:, problem.m:]).T)
