"""CCDA: combined constraint data association (Bailey, Nebot, Rosenblatt & Durrant-Whyte, ICRA 2000;
Bailey's thesis, 2002). A vertex per pairing (i, j) passing the unary constraint, an edge between
(i, j) and (i', j'), i ≠ i', j ≠ j', passing the binary one; the answer is a maximum clique. In
measurement space:

* unary: ``NIS_ij <= χ²_d(c)``;
* binary: ``Δ = wrap((z_i - z_i') - (zhat_j - zhat_j'))``,
  ``S_Δ = P_jj + P_j'j' - P_jj' - P_j'j + R_i + R_i'``, ``NIS_Δ = |L⁻¹Δ|² <= χ²_d(c)``
  (``difference_nis``): blind to an error shifting both predictions alike, but what a pose error
  does differently to the two is weighed by ``S_Δ``.

The binary constraint needs no pose, so ``unary=False`` associates without a pose prior, Bailey's
point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..association.compatibility import (
    chi2_threshold,
    difference_nis_kernel,
    individually_compatible,
    marginal_blocks,
    wrap_mask,
)
from ..association.problem import Problem
from ..errors import UserError
from ..validation import in_range
from .base import CONFIDENCE, Associator
from .max_clique import max_clique, set_edge

MAX_VERTICES = 20_000   # V vertices take V²/8 bytes of adjacency bits: 50 MB here


@njit(cache=True)
def correspondence_graph(P, Pd, z, zhat, R, wrap, feats, lms, gate):
    """Bit adjacency (V, ⌈V/64⌉) of the vertices (``feats[v]``, ``lms[v]``): an edge where the
    two pairings use different features and landmarks and their ``difference_nis`` passes ``gate``."""
    V, d = feats.shape[0], z.shape[1]
    adj = np.zeros((V, (V + 63) // 64), np.uint64)
    S, y = np.empty((d, d)), np.empty(d)
    for a in range(V):
        for b in range(a + 1, V):
            if feats[a] != feats[b] and lms[a] != lms[b] and \
                    difference_nis_kernel(P, Pd, z, zhat, R, wrap, feats[a], lms[a], feats[b], lms[b], S, y) <= gate:
                set_edge(adj, a, b)
    return adj


@njit(cache=True)
def _pair_nis(prob, work, u, v):
    """``difference_nis`` of vertices u and v; ``prob`` = (P, Pd, z, zhat, R, wrap, feats, lms)."""
    P, Pd, z, zhat, R, wrap, feats, lms = prob
    S, y = work
    return difference_nis_kernel(P, Pd, z, zhat, R, wrap, feats[u], lms[u], feats[v], lms[v], S, y)


@njit(cache=True)
def _adjacent(adj, u, v):
    return (adj[u, v >> 6] >> np.uint64(v & 63)) & np.uint64(1) != 0


@njit(cache=True)
def _outsiders(adj, C, inside):
    """Vertices outside the clique ``C`` adjacent to all its members but one or two: (vertices,
    (q, 2) positions in ``C`` of the members each misses, -1 for none)."""
    V, k = adj.shape[0], C.shape[0]
    verts = np.empty(V, np.int64)
    miss = np.full((V, 2), -1, np.int64)
    q = 0
    for u in range(V):
        if inside[u]:
            continue
        count = 0
        for a in range(k):
            if not _adjacent(adj, u, C[a]):
                if count < 2:
                    miss[q, count] = a
                count += 1
                if count > 2:
                    break
        if 1 <= count <= 2:
            verts[q] = u
            q += 1
    return verts[:q], miss[:q]


@njit(cache=True)
def _union2(m1, m2):
    """The two members missed by a pair of outsiders together, or (-1, -1) if not exactly two."""
    a, b = m1[0], m1[1]
    for c in m2:
        if c >= 0 and c != a and c != b:
            if b >= 0:
                return -1, -1
            b = c
    return (a, b) if b >= 0 else (-1, -1)


@njit(cache=True)
def _best_swap(adj, prob, work, C, D, verts, miss):
    """The swap lowering the clique's total binary NIS most: (delta, members out a, b (b = -1:
    one-for-one), vertices in u1, u2); delta 0 and a = -1 when none does."""
    q, k = verts.shape[0], D.shape[0]
    E = np.zeros((q, k))             # NIS_Δ of each outsider with each member it is adjacent to
    for t in range(q):
        for c in range(k):
            if c != miss[t, 0] and c != miss[t, 1]:
                E[t, c] = _pair_nis(prob, work, verts[t], C[c])
    row, esum = D.sum(axis=1), E.sum(axis=1)
    best_delta, best_a, best_b, best_u1, best_u2 = 0.0, -1, -1, -1, -1
    for t in range(q):               # one for one: u replaces the one member it misses
        a = miss[t, 0]
        if miss[t, 1] < 0 and esum[t] - row[a] < best_delta:
            best_delta, best_a, best_b, best_u1, best_u2 = esum[t] - row[a], a, -1, verts[t], -1
    for t in range(q):               # two for two: adjacent u1, u2 replace the two members they miss
        for r in range(t + 1, q):
            a, b = _union2(miss[t], miss[r])
            if a < 0 or not _adjacent(adj, verts[t], verts[r]):
                continue
            delta = (esum[t] - E[t, a] - E[t, b] + esum[r] - E[r, a] - E[r, b]
                     + _pair_nis(prob, work, verts[t], verts[r]) - row[a] - row[b] + D[a, b])
            if delta < best_delta:
                best_delta, best_a, best_b, best_u1, best_u2 = delta, a, b, verts[t], verts[r]
    return best_delta, best_a, best_b, best_u1, best_u2


@njit(cache=True)
def swap_descent(adj, clique, P, Pd, z, zhat, R, wrap, feats, lms):
    """The tie rule: lower the clique's total binary NIS ``Σ_{u, v in C} NIS_Δ(u, v)`` by swaps
    keeping a clique of the same size (one member for an outside vertex adjacent to the others, or
    two for two: two landmarks trading features), largest decrease first, until none decreases it.
    Returns (clique, swaps made)."""
    d, k, V = z.shape[1], clique.shape[0], adj.shape[0]
    C = clique.copy()
    prob = (P, Pd, z, zhat, R, wrap, feats, lms)
    work = (np.empty((d, d)), np.empty(d))
    D = np.zeros((k, k))
    for a in range(k):
        for b in range(a + 1, k):
            D[a, b] = D[b, a] = _pair_nis(prob, work, C[a], C[b])
    inside = np.zeros(V, np.bool_)
    inside[C] = True
    swaps = 0
    while swaps < V:                 # every swap lowers the total, so no cycle; a guard all the same
        verts, miss = _outsiders(adj, C, inside)
        delta, a, b, u1, u2 = _best_swap(adj, prob, work, C, D, verts, miss)
        if a < 0:
            break
        for pos, u in ((a, u1), (b, u2)):
            if pos >= 0:
                inside[C[pos]], inside[u] = False, True
                C[pos] = u
        for pos in (a, b):
            for c in range(k):
                if pos >= 0 and c != pos:
                    D[pos, c] = D[c, pos] = _pair_nis(prob, work, C[pos], C[c])
        swaps += 1
    return C, swaps


@dataclass
class CCDA(Associator):
    """A maximum clique of the correspondence graph, found exactly (``max_clique``). Maximum cliques
    are seldom unique and enumerating them is dear, so ties are broken by swaps lowering the total
    binary NIS (``swap_descent``); deterministic. As in Bailey's CCDA the clique is not put to the
    joint test.

    confidence: the gate ``c`` of both tests (higher raises recall but slows large problems,
        ``benchmarks/ccda_scale.py``).
    unary: apply the individual gate; False makes every pair a vertex (at most ``MAX_VERTICES``).
    max_nodes: node budget of the clique search; when spent, the largest clique so far with
        ``info["timed_out"]``.

    ``info``: ``timed_out``, ``proven_optimal``, ``nodes``, ``vertices``, ``swaps``.
    """

    name = "ccda"
    summary = "combined constraint data association: maximum clique of pairwise consistent pairings"
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    unary: bool = True
    max_nodes: int = field(default=100_000, metadata=in_range(1))

    def associate(self, problem: Problem) -> np.ndarray:
        problem.validate()              # reads P's cross terms (a no-op once checked)
        out = self.empty(problem)
        self.info = {"timed_out": False, "proven_optimal": True, "nodes": 0, "vertices": 0, "swaps": 0}
        if problem.m == 0 or problem.n == 0:
            return out
        allowed = individually_compatible(problem, self.confidence) if self.unary else np.ones((problem.m, problem.n), bool)
        lms, feats = np.nonzero(allowed.T)          # vertices by landmark, then feature
        if len(lms) > MAX_VERTICES:
            hint = "the individual gate passes too many pairs" if self.unary else "use unary=True"
            raise UserError(f"ccda: the correspondence graph would have {len(lms)} vertices (m={problem.m}, "
                            f"n={problem.n}, unary={self.unary}), more than {MAX_VERTICES}: {hint}")
        args = (problem.P, np.ascontiguousarray(marginal_blocks(problem)), problem.z, problem.zhat, problem.R,
                wrap_mask(problem))
        adj = correspondence_graph(*args, feats, lms, chi2_threshold(problem.d, self.confidence))
        bound = min(len(np.unique(lms)), len(np.unique(feats)))
        clique, nodes, timed_out = max_clique(adj, bound, int(self.max_nodes))
        clique, swaps = swap_descent(adj, clique, *args, feats, lms)
        out[lms[clique]] = feats[clique]
        self.info = {"timed_out": timed_out, "proven_optimal": not timed_out, "nodes": nodes,
                     "vertices": int(len(lms)), "swaps": int(swaps)}
        return out
