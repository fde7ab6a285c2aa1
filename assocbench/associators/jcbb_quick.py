"""JCBB's first step in one compiled call: the individual gate, the quick exact search and the
classic first dive (``anytime_search``'s step 1). Most frames are small problems this step proves
alone, so one entry into compiled code with no intermediate array returned to Python is their whole
cost. The arithmetic is the separate kernels', so answers and node counts are theirs bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import gate_mask_kernel
from .jcbb_dive import classic_dive
from .jcbb_search import is_matching, jcbb_search


@njit(cache=True)
def quick_jcbb(P, z, zhat, R, wrap, limit, gate, quick_by_count, budget_by_count, prefix_test):
    """Step 1 of the anytime JCBB: the gate ``χ²_d(c) = limit``, then, for ``c`` candidates and
    ``q = min(quick_by_count[c], budget_by_count[c] - c)``: where the compatible pairs form a
    matching, the classic dive, proven at the search's root; else the exact search with ``q`` nodes
    and, where it runs out, the classic dive (``c`` nodes). Returns (features, landmarks, NIS,
    nodes, timed out, the dive's pairings (-1: none), history (h, 3), ``ic`` (m, n), the
    candidates); not timed out: proven (unless ``prefix_test``)."""
    ic, candidates = gate_mask_kernel(P, z, zhat, R, wrap, limit)
    c = candidates.shape[0]
    budget = min(quick_by_count[c], budget_by_count[c] - c)
    if is_matching(ic):
        return _from_dive(ic, P, z, zhat, R, wrap, gate, candidates, budget, prefix_test)
    none = np.zeros(0, np.int64)
    feats, lms, used, timed_out, h_nodes, h_k, h_nis = jcbb_search(ic, P, z, zhat, R, wrap, gate, budget,
                                                                   prefix_test, none, none, 0.0)
    spent = min(used, max(budget, 0))
    if not timed_out:
        return feats, lms, h_nis[-1], spent, False, -1, _history(h_nodes, h_k, h_nis, 0), ic, candidates
    d_feats, d_lms, d_nis, _ = classic_dive(ic, P, z, zhat, R, wrap, gate, candidates, False)
    history = np.empty((2, 3))
    history[0, 0], history[0, 1], history[0, 2] = c, d_lms.shape[0], d_nis
    rows = 1
    k, nis = lms.shape[0], h_nis[-1]
    if k > d_lms.shape[0] or (k == d_lms.shape[0] and nis < d_nis):
        history[1, 0], history[1, 1], history[1, 2] = c + spent, k, nis
        rows = 2
    else:
        feats, lms, nis = d_feats, d_lms, d_nis
    return feats, lms, nis, c + spent, True, d_lms.shape[0], history[:rows], ic, candidates


@njit(cache=True)
def _from_dive(ic, P, z, zhat, R, wrap, gate, candidates, budget, prefix_test):
    """``quick_jcbb``'s first branch: the classic dive, then the search from it with ``budget`` nodes."""
    c = candidates.shape[0]
    feats, lms, nis, _ = classic_dive(ic, P, z, zhat, R, wrap, gate, candidates, False)
    b_feats, b_lms, used, timed_out, h_nodes, h_k, h_nis = jcbb_search(ic, P, z, zhat, R, wrap, gate, budget,
                                                                       prefix_test, feats, lms, nis)
    history = _history(h_nodes, h_k, h_nis, c)     # the first row: the dive, at c nodes
    return (b_feats, b_lms, h_nis[-1], c + min(used, max(budget, 0)), timed_out, lms.shape[0], history, ic,
            candidates)


@njit(cache=True)
def _history(h_nodes, h_k, h_nis, offset):
    """A search's improvements as rows ``(nodes + offset, pairings, NIS)``."""
    out = np.empty((h_nodes.shape[0], 3))
    for t in range(h_nodes.shape[0]):
        out[t, 0], out[t, 1], out[t, 2] = h_nodes[t] + offset, h_k[t], h_nis[t]
    return out


@njit(cache=True)
def quick_jcbb_into(out, P, z, zhat, R, wrap, limit, gate, quick_by_count, budget_by_count, prefix_test):
    """``quick_jcbb`` writing the hypothesis into ``out`` (n,) (each landmark's feature, -1 for
    none; arrives all -1) and returning only (NIS, nodes, timed out, the dive's pairings, history as
    ``(nodes, pairings, NIS)`` tuples): each array handed back to Python costs as much as the rest
    of a small problem's Python side. Later steps recompute the mask with
    ``compatibility.gate_mask``."""
    feats, lms, nis, nodes, timed_out, dive_k, history, _, _ = quick_jcbb(P, z, zhat, R, wrap, limit, gate,
                                                                          quick_by_count, budget_by_count,
                                                                          prefix_test)
    for t in range(lms.shape[0]):
        out[lms[t]] = feats[t]
    rows = [(0, 0, 0.0)] * 0
    for t in range(history.shape[0]):
        rows.append((int(history[t, 0]), int(history[t, 1]), history[t, 2]))
    return nis, nodes, timed_out, dive_k, rows
