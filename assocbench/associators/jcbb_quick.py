"""JCBB's first step in one compiled call: the individual gate, the classic first dive and the
quick exact search from it (``anytime_search``'s step 1).

Most frames of a run are small problems that this step proves on its own, so their whole cost
is this call: one entry into compiled code instead of three, and no intermediate array returned
to Python (each dispatch and each array handed back costs about a microsecond, as much as a
search node at n = 10). The arithmetic is that of the separate kernels, so the answer and the
nodes counted are theirs, bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import gate_mask_kernel
from .jcbb_dive import classic_dive
from .jcbb_search import jcbb_search


@njit(cache=True)
def quick_jcbb(P, z, zhat, R, wrap, limit, gate, quick_by_count, budget_by_count, prefix_test):
    """Step 1 of the anytime JCBB on a problem's arrays: the individual gate ``χ²_d(c) = limit``
    (``gate_mask_kernel``), the classic dive over the landmarks with a compatible feature, and
    the exact search from it with ``min(quick_by_count[c], budget_by_count[c] - c)`` nodes for
    ``c`` such landmarks (``anytime_search.budget_tables``) (``gate[k] = χ²_{dk}(c)``).

    Returns (features, landmarks, NIS of the best hypothesis, nodes spent (the dive's one per
    landmark plus the search's), timed out, history (h, 3) of ``(nodes, pairings, NIS)`` per
    improvement (the dive's first), the mask ``ic`` (m, n) and the candidate landmarks). A call
    that did not time out has proven its answer (unless ``prefix_test``); one that did hands
    ``ic`` and the candidates to the later steps."""
    ic, candidates = gate_mask_kernel(P, z, zhat, R, wrap, limit)
    c = candidates.shape[0]
    feats, lms, nis, _ = classic_dive(ic, P, z, zhat, R, wrap, gate, candidates, False)
    budget = min(quick_by_count[c], budget_by_count[c] - c)
    b_feats, b_lms, used, timed_out, h_nodes, h_k, h_nis = jcbb_search(ic, P, z, zhat, R, wrap, gate, budget,
                                                                       prefix_test, feats, lms, nis)
    history = np.empty((h_nodes.shape[0], 3))
    history[0, 0], history[0, 1], history[0, 2] = c, lms.shape[0], nis
    for t in range(1, h_nodes.shape[0]):
        history[t, 0], history[t, 1], history[t, 2] = c + h_nodes[t], h_k[t], h_nis[t]
    spent = c + min(used, max(budget, 0))
    return b_feats, b_lms, history[-1, 2], spent, timed_out, history, ic, candidates
