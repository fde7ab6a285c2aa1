"""RJC's compiled part: the joint nearest-neighbour completion of a sample's hypothesis, growing the
joint factor of ``association.compatibility`` pairing by pairing. Its work arrays (``make_work``)
serve every iteration of a call: a completion reads only rows it wrote and clears the moments it
starts from.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import advance_moments, append_rows, empty_factor, whitened_nis


def adjacency(ic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Individually compatible landmarks of each feature as CSR arrays ``(start, lms)``: feature
    ``i``'s are ``lms[start[i]:start[i + 1]]``, ascending."""
    start = np.zeros(ic.shape[0] + 1, np.int64)
    np.cumsum(ic.sum(axis=1), out=start[1:])
    return start, np.nonzero(ic)[1].astype(np.int64)


def make_work(n: int, d: int) -> tuple[np.ndarray, ...]:
    """One completion's work arrays ``(Mt, w, C, G, S, y, L, w2)`` (``compatibility.empty_factor``)."""
    return empty_factor(n, d)


@njit(cache=True)
def _open_columns(is_open, demand, cols):
    """Landmarks a later pairing may still involve, into ``cols``; returns how many (the only
    columns read again)."""
    nc = 0
    for l in range(is_open.shape[0]):
        if is_open[l] and demand[l] > 0:
            cols[nc] = l
            nc += 1
    return nc


@njit(cache=True)
def _append(k, nis, i, j, P, z, zhat, R, wrap, work, cols, pair_i, pair_j):
    """Append pairing (i, j) to the hypothesis of size ``k``; the moments of ``cols`` follow.
    Returns the new NIS."""
    Mt, w, C, G, S, y, L, w2 = work
    d = z.shape[1]
    dn = whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
    append_rows(Mt, w, k * d, P, j, L, w2, cols)
    advance_moments(Mt, k * d, w2, cols, C, G, C, G)
    pair_i[k], pair_j[k] = i, j
    return nis + dn


@njit(cache=True)
def complete(seed_i, seed_j, order, in_sample, start, adj, P, z, zhat, R, wrap, gate, best_k, best_nis, work,
             pair_i, pair_j):
    """Grow the sample's hypothesis over the other features of ``order``: each takes the open
    compatible landmark with the smallest joint NIS increase keeping ``NIS ≤ χ²_{d(k+1)}``, or none;
    pairings into ``pair_i``, ``pair_j``. Returns (k, NIS), k = -1 once it can no longer beat
    (``best_k``, ``best_nis``)."""
    Mt, w, C, G, S, y, L, w2 = work
    n = zhat.shape[0]
    C[:] = 0.0                                  # the empty hypothesis
    G[:] = 0.0
    is_open = np.ones(n, np.bool_)
    demand = np.zeros(n, np.int64)              # features still to visit that could pair with each landmark
    left = 0
    for i in order:
        if not in_sample[i]:
            left += 1
            for e in range(start[i], start[i + 1]):
                demand[adj[e]] += 1
    for a in range(seed_i.shape[0]):            # the sample's landmarks are needed until appended
        demand[seed_j[a]] += 1
    cols = np.empty(n, np.int64)
    k, nis = 0, 0.0
    for a in range(seed_i.shape[0]):
        j = seed_j[a]
        is_open[j] = False
        demand[j] -= 1
        nc = _open_columns(is_open, demand, cols)
        nis = _append(k, nis, seed_i[a], j, P, z, zhat, R, wrap, work, cols[:nc], pair_i, pair_j)
        k += 1
    for i in order:
        if in_sample[i]:
            continue
        if k + left < best_k or (k + left == best_k and nis >= best_nis):
            return -1, nis
        left -= 1
        pick, least = -1, np.inf
        for e in range(start[i], start[i + 1]):
            j = adj[e]
            demand[j] -= 1
            if is_open[j]:
                dn = whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
                if dn < least and nis + dn <= gate[k + 1]:
                    pick, least = j, dn
        if pick < 0:
            continue
        is_open[pick] = False
        nc = _open_columns(is_open, demand, cols)
        nis = _append(k, nis, i, pick, P, z, zhat, R, wrap, work, cols[:nc], pair_i, pair_j)
        k += 1
    return k, nis
