"""The classic JCBB first dive, compiled: the incumbent the exact search starts from.

Neira & Tardós (2001) walk the landmarks in a fixed order and at each take the compatible pairing
with the smallest joint NIS increase that keeps the hypothesis jointly compatible
(``NIS(H + p) <= χ²_{d(k+1)}(c)``), or none. One pass, so always run in full: a budgeted search from
it never returns fewer pairings. The factor keeps every landmark's column (about twice the work of
keeping those still to visit), so at the end each landmark's conditional moments given the whole
hypothesis give the next dive's order for free.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import append_rows, conditional_moments, empty_factor, whitened_nis


@njit(cache=True)
def classic_dive(ic, P, z, zhat, R, wrap, gate, order, rank=True):
    """First dive of classic JCBB over the landmarks in ``order``: (features, landmarks, NIS) in the
    order made, and ``surest`` (n,): each landmark's least ``NIS(H + (i, j)) - NIS(H)`` given the
    final ``H`` (inf elsewhere; a landmark in ``H`` is measured as if observed twice: a ranking, not
    a test). Without ``rank`` only landmarks still to visit are kept (same hypothesis) and
    ``surest`` is inf. ``ic``: the individual mask, ``gate[k] = χ²_{dk}(c)``."""
    m, n = ic.shape
    d = z.shape[1]
    Mt, w, C, G, S, y, L, w2 = empty_factor(n, d)
    free = np.ones(m, np.bool_)
    pair_i = np.empty(n, np.int64)
    pair_j = np.empty(n, np.int64)
    k, nis = 0, 0.0
    for t in range(order.shape[0]):
        j = order[t]
        conditional_moments(Mt, w, k * d, j, C[j], G[j])
        best_i, best_dn = -1, np.inf
        for i in range(m):
            if free[i] and ic[i, j]:
                dn = whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
                if nis + dn <= gate[k + 1] and dn < best_dn:
                    best_i, best_dn = i, dn
        if best_i < 0:
            continue
        whitened_nis(P, z, zhat, R, wrap, best_i, j, C, G, S, y, L, w2)   # its L and w2 again
        append_rows(Mt, w, k * d, P, j, L, w2, order if rank else order[t + 1:])
        pair_i[k], pair_j[k] = best_i, j
        free[best_i] = False
        nis += best_dn
        k += 1
    surest = np.full(n, np.inf)
    for j in order[:order.shape[0] if rank else 0]:
        conditional_moments(Mt, w, k * d, j, C[j], G[j])
        for i in range(m):
            if ic[i, j]:
                surest[j] = min(surest[j], whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2))
    return pair_i[:k], pair_j[:k], nis, surest


@njit(cache=True)
def greedy_dive(ic, P, z, zhat, R, wrap, gate, candidates):
    """Global greedy dive: of all free compatible pairings, add the smallest joint NIS increase that
    passes the prefix test, until none does; it never commits a landmark before a surer pairing
    elsewhere has pinned the pose."""
    m, n = ic.shape
    d = z.shape[1]
    Mt, w, C, G, S, y, L, w2 = empty_factor(n, d)
    free = np.ones(m, np.bool_)
    open_lm = np.zeros(n, np.bool_)
    open_lm[candidates] = True
    pair_i = np.empty(n, np.int64)
    pair_j = np.empty(n, np.int64)
    k, nis = 0, 0.0
    while True:
        best_i, best_j, best_dn = -1, -1, np.inf
        for j in candidates:
            if not open_lm[j]:
                continue
            conditional_moments(Mt, w, k * d, j, C[j], G[j])
            for i in range(m):
                if free[i] and ic[i, j]:
                    dn = whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
                    if nis + dn <= gate[k + 1] and dn < best_dn:
                        best_i, best_j, best_dn = i, j, dn
        if best_i < 0:
            break
        conditional_moments(Mt, w, k * d, best_j, C[best_j], G[best_j])
        whitened_nis(P, z, zhat, R, wrap, best_i, best_j, C, G, S, y, L, w2)
        append_rows(Mt, w, k * d, P, best_j, L, w2, candidates)
        pair_i[k], pair_j[k] = best_i, best_j
        free[best_i] = False
        open_lm[best_j] = False
        nis += best_dn
        k += 1
    return pair_i[:k], pair_j[:k], nis


@njit(cache=True)
def fail_first_order(ic, P, z, zhat, R, wrap, candidates):
    """``candidates`` fail first: fewest compatible features, ties by the smallest individual NIS
    (stable), so a dive places the pose with the landmarks that have no choice."""
    m = ic.shape[0]
    d = z.shape[1]
    n = zhat.shape[0]
    C, G = np.zeros((n, d)), np.zeros((n, d, d))     # the empty hypothesis
    S, y, L, w2 = np.empty((d, d)), np.empty(d), np.empty((d, d)), np.empty(d)
    degree = np.empty(candidates.shape[0])
    least = np.full(candidates.shape[0], np.inf)
    for t in range(candidates.shape[0]):
        j = candidates[t]
        count = 0
        for i in range(m):
            if ic[i, j]:
                count += 1
                least[t] = min(least[t], whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2))
        degree[t] = count
    by_least = np.argsort(least, kind="mergesort")
    return candidates[by_least[np.argsort(degree[by_least], kind="mergesort")]]
