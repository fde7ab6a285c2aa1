"""The JCBB search, compiled: depth-first branch and bound with forward checking.

Iterative (an explicit stack of levels) so numba compiles it. The joint test is the
incremental one of ``association.compatibility``: the hypothesis keeps ``M = L⁻¹ P[J, :]``
(transposed, and only for the landmarks still in play) and, for every landmark in play, its
conditional moments ``c_j = Xᵀw``, ``G_j = XᵀX`` (``conditional_moments``), stored per
hypothesis size ``k``. Testing a pairing then costs O(d³) whatever ``k``, and appending one
O(kd·d·r) for ``r`` landmarks in play; backtracking just lowers ``k``.

Each level holds one node: the landmark it branches on, its candidate features sorted by
joint NIS increase, and which child comes next.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import advance_moments, append_rows, whitened_pair


@njit(cache=True)
def _max_matching(lms, feats, n, m):
    """Size of a maximum bipartite matching of the pairs (lms[q], feats[q]) (augmenting paths,
    breadth first; visit stamps instead of clearing arrays, so a search costs what it touches)."""
    q = lms.shape[0]
    start = np.zeros(n + 1, np.int64)
    for t in range(q):
        start[lms[t] + 1] += 1
    for a in range(n):
        start[a + 1] += start[a]
    adj = feats[np.argsort(lms, kind="mergesort")]
    match_f = np.full(m, -1, np.int64)   # landmark matched to each feature
    match_l = np.full(n, -1, np.int64)   # feature matched to each landmark
    parent = np.empty(m, np.int64)       # landmark that reached a feature in the current search
    stamp_f = np.zeros(m, np.int64)      # search in which a feature was last reached
    stamp_l = np.zeros(n, np.int64)
    queue = np.empty(n, np.int64)
    size = 0
    for root in range(n):
        if start[root] == start[root + 1]:
            continue
        tag = root + 1
        head, tail = 0, 1
        queue[0] = root
        stamp_l[root] = tag
        found = -1
        while head < tail and found < 0:
            lm = queue[head]
            head += 1
            for e in range(start[lm], start[lm + 1]):
                f = adj[e]
                if stamp_f[f] == tag:
                    continue
                stamp_f[f] = tag
                parent[f] = lm
                if match_f[f] < 0:
                    found = f
                    break
                nxt = match_f[f]
                if stamp_l[nxt] != tag:
                    stamp_l[nxt] = tag
                    queue[tail] = nxt
                    tail += 1
        f = found
        while f >= 0:           # flip the augmenting path back to the root
            lm = parent[f]
            prev = match_l[lm]
            match_f[f] = lm
            match_l[lm] = f
            f = prev
        size += int(found >= 0)
    return size


@njit(cache=True)
def _count_bound(lms, feats, keep, n, m):
    seen_l = np.zeros(n, np.bool_)
    seen_f = np.zeros(m, np.bool_)
    nl, nf = 0, 0
    for t in range(lms.shape[0]):
        if keep[t]:
            if not seen_l[lms[t]]:
                seen_l[lms[t]] = True
                nl += 1
            if not seen_f[feats[t]]:
                seen_f[feats[t]] = True
                nf += 1
    return min(nl, nf)


@njit(cache=True)
def _least_increments(lms, feats, dnis, keep, n, m):
    """Sorted least NIS increments per landmark and per feature over the kept pairings (only the
    landmarks and features that have one)."""
    lm_min = np.full(n, np.inf)
    f_min = np.full(m, np.inf)
    for t in range(lms.shape[0]):
        if keep[t]:
            lm_min[lms[t]] = min(lm_min[lms[t]], dnis[t])
            f_min[feats[t]] = min(f_min[feats[t]], dnis[t])
    return np.sort(lm_min[lm_min < np.inf]), np.sort(f_min[f_min < np.inf])


@njit(cache=True)
def _forward_check(in_play, free, adj_start, adj_feat, P, z, zhat, R, wrap, C, G, lms, feats, dnis, work):
    """NIS increase of every pairing of a landmark in play with a free feature; returns their count.
    ``work`` holds the (d, d) and (d,) work arrays of ``whitened_pair``: S, y, L, w2."""
    S, y, L, w2 = work
    q = 0
    for j in range(in_play.shape[0]):
        if not in_play[j]:
            continue
        for e in range(adj_start[j], adj_start[j + 1]):
            i = adj_feat[e]
            if free[i]:
                lms[q], feats[q] = j, i
                dnis[q] = whitened_pair(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)[0]
                q += 1
    return q


@njit(cache=True)
def _bound(lms, feats, dnis, nis, k, gate, best_k, n, m):
    """(b, floor, keep): at most ``b`` more pairings can join, the final NIS is at least ``floor``,
    and ``keep`` marks the pairings that can still be part of a jointly compatible completion."""
    q = lms.shape[0]
    keep = np.ones(q, np.bool_)
    bound = -1
    while True:     # a pairing that breaks the loosest gate it could still face leaves the subtree
        nb = _count_bound(lms, feats, keep, n, m)
        if nb == bound:
            break
        bound = nb
        for t in range(q):
            if keep[t] and nis + dnis[t] > gate[k + bound]:
                keep[t] = False
    floor = nis
    if bound > 0 and k + bound >= best_k:
        sel = np.flatnonzero(keep)
        bound = _max_matching(lms[sel], feats[sel], n, m)
        # b more pairings use b distinct landmarks and b distinct features; the final NIS is at
        # least NIS(H + p) for each of its pairings p, so at least the b-th smallest of the
        # per-landmark (and per-feature) least increments. It must pass gate[k + b].
        lm_min, f_min = _least_increments(lms, feats, dnis, keep, n, m)
        while bound > 0 and nis + max(lm_min[bound - 1], f_min[bound - 1]) > gate[k + bound]:
            bound -= 1
        if bound > 0:
            floor = nis + max(lm_min[bound - 1], f_min[bound - 1])
    return bound, floor, keep


@njit(cache=True)
def _branch_landmark(lms, dnis, keep, n, m):
    """(landmark to branch on, kept pairings per landmark): the fewest kept pairings (fail first,
    a narrow tree), ties to the smallest least NIS increase (the surest pairing first, so a dive
    that must stop early has pinned the pose with its most certain pairings)."""
    counts = np.zeros(n, np.int64)
    least = np.full(n, np.inf)
    for t in range(lms.shape[0]):
        if keep[t]:
            counts[lms[t]] += 1
            least[lms[t]] = min(least[lms[t]], dnis[t])
    jstar, fewest, surest = -1, m + 1, np.inf
    for j in range(n):
        if counts[j] > 0 and (counts[j] < fewest or (counts[j] == fewest and least[j] < surest)):
            jstar, fewest, surest = j, counts[j], least[j]
    return jstar, counts


@njit(cache=True)
def _push(level, k, i, j, lvl_cols, lvl_ncols, P, z, zhat, R, wrap, Mt, w, C, G, work):
    """Append pairing (i, j) to the hypothesis of size k; moments of size k + 1 for the landmarks in
    play below this level. Returns the NIS increase."""
    d = z.shape[1]
    kd = k * d
    S, y, L, w2 = work
    dn = whitened_pair(P, z, zhat, R, wrap, i, j, C[k], G[k], S, y, L, w2)[0]
    cols = lvl_cols[level, :lvl_ncols[level]]
    append_rows(Mt, w, kd, P, j, L, w2, cols)
    advance_moments(Mt, kd, w2, cols, C[k], G[k], C[k + 1], G[k + 1])
    return dn


@njit(cache=True)
def jcbb_search(ic, P, z, zhat, R, wrap, gate, max_nodes, prefix_test):
    """Best hypothesis (pairs_i, pairs_j arrays of its pairings), nodes visited, timed out."""
    m, n = ic.shape
    d = z.shape[1]
    adj_start = np.zeros(n + 1, np.int64)          # individually compatible features per landmark
    for j in range(n):
        adj_start[j + 1] = adj_start[j] + np.sum(ic[:, j])
    adj_feat = np.empty(adj_start[n], np.int64)
    for j in range(n):
        adj_feat[adj_start[j]:adj_start[j + 1]] = np.flatnonzero(ic[:, j])
    Mt = np.zeros((n * d, n * d))                  # L⁻¹ P[J, :], transposed
    w = np.zeros(n * d)
    C = np.zeros((n + 1, n, d))                    # conditional moments at each hypothesis size
    G = np.zeros((n + 1, n, d, d))
    nis_at = np.zeros(n + 1)                       # NIS with k pairings
    pair_i = np.full(n, -1, np.int64)
    pair_j = np.full(n, -1, np.int64)
    free = np.ones(m, np.bool_)
    levels = n + 2
    remaining = np.zeros((levels, n), np.bool_)
    for j in range(n):
        remaining[0, j] = adj_start[j + 1] > adj_start[j]
    lvl_j = np.zeros(levels, np.int64)
    lvl_cand = np.zeros((levels, m), np.int64)
    lvl_dnis = np.zeros((levels, m))
    lvl_ncand = np.zeros(levels, np.int64)
    lvl_njc = np.zeros(levels, np.int64)
    lvl_next = np.zeros(levels, np.int64)
    lvl_done = np.zeros(levels, np.bool_)
    lvl_pushed = np.zeros(levels, np.bool_)
    lvl_cols = np.zeros((levels, n), np.int64)     # landmarks still in play below each level
    lvl_ncols = np.zeros(levels, np.int64)
    best_k, best_nis = 0, 0.0
    best_i = np.full(n, -1, np.int64)
    best_j = np.full(n, -1, np.int64)
    lms_buf = np.empty(adj_start[n], np.int64)
    feats_buf = np.empty(adj_start[n], np.int64)
    dnis_buf = np.empty(adj_start[n])
    work = (np.empty((d, d)), np.empty(d), np.empty((d, d)), np.empty(d))   # whitened_pair's S, y, L, w2
    k = 0
    nodes = 0
    timed_out = False
    level = 0
    entering = True
    while level >= 0:
        if entering:
            entering = False
            nodes += 1
            if nodes > max_nodes:
                timed_out = True
                break
            nis = nis_at[k]
            if nis <= gate[k] and (k > best_k or (k == best_k and nis < best_nis)):
                best_k, best_nis = k, nis
                best_i[:] = -1
                best_j[:] = -1
                best_i[:k] = pair_i[:k]
                best_j[:k] = pair_j[:k]
            q = _forward_check(remaining[level], free, adj_start, adj_feat, P, z, zhat, R, wrap, C[k], G[k],
                               lms_buf, feats_buf, dnis_buf, work)
            lms, feats, dnis = lms_buf[:q], feats_buf[:q], dnis_buf[:q]
            bound, floor, keep = _bound(lms, feats, dnis, nis, k, gate, best_k, n, m)
            if bound == 0 or k + bound < best_k or (k + bound == best_k and floor >= best_nis):
                lvl_done[level] = True
            else:
                jstar, counts = _branch_landmark(lms, dnis, keep, n, m)
                nc = 0
                for t in range(q):
                    if keep[t] and lms[t] == jstar:
                        lvl_cand[level, nc] = feats[t]
                        lvl_dnis[level, nc] = dnis[t]
                        nc += 1
                order = np.argsort(lvl_dnis[level, :nc], kind="mergesort")
                lvl_cand[level, :nc] = lvl_cand[level, :nc][order]
                lvl_dnis[level, :nc] = lvl_dnis[level, :nc][order]
                n_jc = 0                                     # children that stay jointly compatible
                while n_jc < nc and nis + lvl_dnis[level, n_jc] <= gate[k + 1]:
                    n_jc += 1
                lvl_ncand[level] = nc
                lvl_njc[level] = n_jc
                lvl_j[level] = jstar
                lvl_next[level] = 0
                lvl_done[level] = False
                remaining[level + 1, :] = counts > 0
                remaining[level + 1, jstar] = False
                cols = np.flatnonzero(remaining[level + 1])
                lvl_ncols[level] = cols.shape[0]
                lvl_cols[level, :cols.shape[0]] = cols
            continue
        # back from a child: undo its pairing
        if lvl_pushed[level]:
            k -= 1
            free[pair_i[k]] = True
            lvl_pushed[level] = False
        if lvl_done[level]:
            level -= 1
            continue
        # children in order: the compatible pairings, then "unassociated", then the pairings that
        # break the joint test for now (needed for exactness, not by the classic prefix test). So
        # the first dive is the classic JCBB dive and meets a jointly compatible hypothesis early.
        slot = lvl_next[level]
        lvl_next[level] += 1
        n_jc = lvl_njc[level]
        last = n_jc if prefix_test else lvl_ncand[level]
        if slot > last:
            lvl_done[level] = True
            level -= 1
            continue
        if slot != n_jc:
            a = slot if slot < n_jc else slot - 1
            i, j = lvl_cand[level, a], lvl_j[level]
            dn = _push(level, k, i, j, lvl_cols, lvl_ncols, P, z, zhat, R, wrap, Mt, w, C, G, work)
            pair_i[k], pair_j[k] = i, j
            nis_at[k + 1] = nis_at[k] + dn
            k += 1
            free[i] = False
            lvl_pushed[level] = True
        else:
            lvl_pushed[level] = False                    # the "unassociated" child
        level += 1
        entering = True
    return best_i[:best_k], best_j[:best_k], nodes, timed_out
