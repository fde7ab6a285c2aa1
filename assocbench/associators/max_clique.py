"""Exact maximum clique, compiled: Tomita and Seki's MCQ (2003) on bitsets as in San Segundo's BBMC
(2011), vertices in smallest-last order. A node holds the clique ``C`` and its candidates ``P``,
colours ``P`` greedily and branches from the highest colour down: a clique in ``P`` has at most as
many vertices as colours, so colour ``k`` ends the node once ``|C| + k`` cannot beat the best (too
low colours stay in ``P`` unlisted). Iterative; nothing is allocated per node.
"""

from __future__ import annotations

import numpy as np
from numba import njit

ONE = np.uint64(1)
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_DEBRUIJN_INDEX = np.zeros(64, np.int64)
for _b in range(64):
    _DEBRUIJN_INDEX[int(((1 << _b) * 0x03F79D71B4CB0A89 % (1 << 64)) >> 58)] = _b


@njit(cache=True)
def _lowest_bit(x):
    """Index of the lowest set bit of a non-zero uint64 (de Bruijn multiplication)."""
    low = x & (~x + ONE)
    return _DEBRUIJN_INDEX[(low * _DEBRUIJN) >> np.uint64(58)]


@njit(cache=True)
def _popcount(x):
    """Number of set bits of a uint64 (SWAR)."""
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return np.int64((x * np.uint64(0x0101010101010101)) >> np.uint64(56))


@njit(cache=True)
def set_edge(adj, a, b):
    """Join vertices ``a`` and ``b`` in the bit adjacency matrix."""
    adj[a, b >> 6] |= ONE << np.uint64(b & 63)
    adj[b, a >> 6] |= ONE << np.uint64(a & 63)


@njit(cache=True)
def _degrees(adj):
    V, W = adj.shape
    degree = np.zeros(V, np.int64)
    for v in range(V):
        for w in range(W):
            degree[v] += _popcount(adj[v, w])
    return degree


@njit(cache=True)
def _permute(adj, order):
    """The adjacency with vertex ``order[a]`` renumbered ``a``."""
    V, W = adj.shape
    rank = np.empty(V, np.int64)
    for a in range(V):
        rank[order[a]] = a
    out = np.zeros((V, W), np.uint64)
    for a in range(V):
        for w in range(W):
            x = adj[order[a], w]
            while x != np.uint64(0):
                r = rank[w * 64 + _lowest_bit(x)]
                x &= x - ONE
                out[a, r >> 6] |= ONE << np.uint64(r & 63)
    return out


@njit(cache=True)
def _degeneracy_order(adj):
    """Smallest-last order (Matula-Beck): repeatedly remove a vertex of least remaining degree
    (lowest index on ties); the order is the reverse of removal, so the densest core comes first."""
    V, W = adj.shape
    degree = _degrees(adj)
    removed = np.zeros(V, np.bool_)
    out = np.empty(V, np.int64)
    for t in range(V - 1, -1, -1):
        pick, least = -1, V + 1
        for v in range(V):
            if not removed[v] and degree[v] < least:
                pick, least = v, degree[v]
        removed[pick] = True
        out[t] = pick
        for w in range(W):
            x = adj[pick, w]
            while x != np.uint64(0):
                degree[w * 64 + _lowest_bit(x)] -= 1
                x &= x - ONE
    return out


@njit(cache=True)
def _colour_sort(P, adj, kmin, order, col, U, Q):
    """Greedy colouring of the candidate bitset ``P``: the vertices of colour >= ``kmin`` into
    ``order``/``col`` by colour (each class in index order); returns how many."""
    W = P.shape[0]
    left = 0
    for w in range(W):
        U[w] = P[w]
        left += _popcount(P[w])
    k, count = 1, 0
    while left > 0:
        for w in range(W):
            Q[w] = U[w]
        for w in range(W):
            while Q[w] != np.uint64(0):
                x = Q[w]
                b = _lowest_bit(x)
                v = w * 64 + b
                Q[w] = x & (x - ONE)
                U[w] &= ~(ONE << np.uint64(b))
                for u in range(w, W):       # v's neighbours cannot share its colour
                    Q[u] &= ~adj[v, u]
                left -= 1
                if k >= kmin:
                    order[count] = v
                    col[count] = k
                    count += 1
        k += 1
    return count


@njit(cache=True)
def _grow(buf, need):
    """``buf`` if it holds ``need`` entries, else a copy twice as large (or ``need``)."""
    if need <= buf.shape[0]:
        return buf
    out = np.empty(max(need, 2 * buf.shape[0]), buf.dtype)
    out[:buf.shape[0]] = buf
    return out


@njit(cache=True)
def _search(adj, levels, max_nodes):
    """The MCQ search on a renumbered graph: (best clique, nodes, timed out). The coloured candidate
    lists share one stack (``order``, ``col``), a child's list over its parent's tried entries, so
    memory follows the current path."""
    V, W = adj.shape
    P = np.zeros((levels + 1, W), np.uint64)      # candidates at each depth
    order = np.empty(2 * V, np.int32)             # coloured candidates to branch on, by colour
    col = np.empty(2 * V, np.int32)
    start = np.zeros(levels + 1, np.int64)
    pos = np.zeros(levels + 1, np.int64)
    clique = np.empty(levels + 1, np.int64)
    best_clique = np.empty(levels + 1, np.int64)
    U, Q = np.empty(W, np.uint64), np.empty(W, np.uint64)
    best = 0
    for v in range(V):
        P[0, v >> 6] |= ONE << np.uint64(v & 63)
    pos[0] = _colour_sort(P[0], adj, 1, order, col, U, Q)
    nodes, timed_out = 1, False
    level = 0
    while level >= 0:
        if pos[level] == 0:
            level -= 1
            continue
        pos[level] -= 1
        t = start[level] + pos[level]
        if level + col[t] <= best:
            level -= 1                   # the rest of the list has no higher colour
            continue
        nodes += 1
        if nodes > max_nodes:
            timed_out = True
            break
        v = order[t]
        clique[level] = v
        left = 0
        for w in range(W):
            x = P[level, w] & adj[v, w]
            P[level + 1, w] = x
            left += _popcount(x)
        P[level, v >> 6] &= ~(ONE << np.uint64(v & 63))   # later siblings exclude v
        size = level + 1
        if size > best:                  # every node's clique counts: a dive cut short still leaves one
            best = size
            best_clique[:size] = clique[:size]
        if left == 0 or size >= levels:  # maximal, or at the caller's bound on the size
            continue
        start[size] = t
        order, col = _grow(order, t + left), _grow(col, t + left)
        pos[size] = _colour_sort(P[size], adj, best - size + 1, order[t:], col[t:], U, Q)
        level = size
    return best_clique[:best].copy(), nodes, timed_out


def max_clique(adj: np.ndarray, size_bound: int, max_nodes: int) -> tuple[np.ndarray, int, bool]:
    """A maximum clique of the graph with bit adjacency ``adj`` (V, ⌈V/64⌉ uint64, symmetric, no
    loops; ``set_edge``). ``size_bound`` bounds the clique size (the stack's depth). Vertices go in
    smallest-last order (``_degeneracy_order``: a far smaller search than MCQ's degree order on
    correspondence graphs). At most ``max_nodes`` nodes. Returns (the clique's vertices, sorted;
    nodes; timed out): maximum when not timed out, else the largest met; the first maximum met
    (deterministic).
    """
    V = adj.shape[0]
    if V == 0:
        return np.zeros(0, np.int64), 0, False
    order = _degeneracy_order(adj)
    levels = int(max(1, min(size_bound, _degrees(adj).max() + 1, V)))
    best, nodes, timed_out = _search(_permute(adj, order), levels, int(max_nodes))
    return np.sort(order[best]), int(nodes), bool(timed_out)
