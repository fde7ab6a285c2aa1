"""The JCBB search, compiled: depth-first branch and bound with forward checking.

Iterative (an explicit stack of levels) so numba compiles it; the joint test is the
incremental one of ``association.compatibility`` (``extension_terms`` / ``append_pair``).
Each level holds one node: the landmark it branches on, its candidate features sorted by
joint NIS increase, and which child comes next.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import append_pair, extension_terms


@njit(cache=True)
def _max_matching(lms, feats, n, m):
    """Size of a maximum bipartite matching of the pairs (lms[q], feats[q]) (augmenting paths)."""
    q = lms.shape[0]
    order = np.argsort(lms, kind="mergesort")
    start = np.zeros(n + 1, np.int64)
    for t in range(q):
        start[lms[t] + 1] += 1
    for a in range(n):
        start[a + 1] += start[a]
    adj = feats[order]
    match_f = np.full(m, -1, np.int64)   # landmark matched to each feature
    parent = np.empty(m, np.int64)       # landmark that reached a feature in this search
    size = 0
    queue = np.empty(n, np.int64)
    seen_lm = np.zeros(n, np.bool_)
    for root in range(n):
        if start[root] == start[root + 1]:
            continue
        seen_lm[:] = False
        parent[:] = -2
        head, tail = 0, 0
        queue[tail] = root
        tail += 1
        seen_lm[root] = True
        found = -1
        while head < tail and found < 0:
            lm = queue[head]
            head += 1
            for e in range(start[lm], start[lm + 1]):
                f = adj[e]
                if parent[f] != -2:
                    continue
                parent[f] = lm
                if match_f[f] < 0:
                    found = f
                    break
                nxt = match_f[f]
                if not seen_lm[nxt]:
                    seen_lm[nxt] = True
                    queue[tail] = nxt
                    tail += 1
        if found < 0:
            continue
        f = found
        while True:             # flip the augmenting path back to the root
            lm = parent[f]
            prev = -1
            for e in range(m):
                if match_f[e] == lm:
                    prev = e
                    break
            match_f[f] = lm
            if lm == root or prev < 0:
                break
            f = prev
        size += 1
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
    """Sorted least NIS increments per landmark and per feature over the kept pairings."""
    lm_min = np.full(n, np.inf)
    f_min = np.full(m, np.inf)
    for t in range(lms.shape[0]):
        if keep[t]:
            lm_min[lms[t]] = min(lm_min[lms[t]], dnis[t])
            f_min[feats[t]] = min(f_min[feats[t]], dnis[t])
    return np.sort(lm_min), np.sort(f_min)


@njit(cache=True)
def jcbb_search(ic, P, z, zhat, R, wrap, gate, max_nodes, prefix_test):
    """Best hypothesis (pairs_i, pairs_j arrays of its pairings), nodes visited, timed out."""
    m, n = ic.shape
    d = z.shape[1]
    M = np.zeros((n * d, n * d))
    w = np.zeros(n * d)
    nis_at = np.zeros(n + 1)           # NIS with k pairings
    pair_i = np.full(n, -1, np.int64)
    pair_j = np.full(n, -1, np.int64)
    free = np.ones(m, np.bool_)
    levels = n + 2
    remaining = np.zeros((levels, n), np.bool_)
    for j in range(n):
        for i in range(m):
            if ic[i, j]:
                remaining[0, j] = True
    lvl_j = np.zeros(levels, np.int64)
    lvl_cand = np.zeros((levels, m), np.int64)
    lvl_dnis = np.zeros((levels, m))
    lvl_ncand = np.zeros(levels, np.int64)
    lvl_njc = np.zeros(levels, np.int64)
    lvl_next = np.zeros(levels, np.int64)
    lvl_done = np.zeros(levels, np.bool_)
    lvl_pushed = np.zeros(levels, np.bool_)
    best_k, best_nis = 0, 0.0
    best_i = np.full(n, -1, np.int64)
    best_j = np.full(n, -1, np.int64)
    lms_buf = np.empty(m * n, np.int64)
    feats_buf = np.empty(m * n, np.int64)
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
            # forward check: every remaining landmark against every free compatible feature
            q = 0
            for j in range(n):
                if remaining[level, j]:
                    for i in range(m):
                        if ic[i, j] and free[i]:
                            lms_buf[q] = j
                            feats_buf[q] = i
                            q += 1
            lms, feats = lms_buf[:q], feats_buf[:q]
            dnis, _ = extension_terms(M, w, k * d, P, z, zhat, R, wrap, lms, feats)
            keep = np.ones(q, np.bool_)
            bound = -1
            while True:
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
                # b more pairings use b distinct landmarks and b distinct features; the final NIS is
                # at least NIS(H + p) for each of its pairings p, so at least the b-th smallest of
                # the per-landmark (and per-feature) least increments. It must pass gate[k + b].
                lm_min, f_min = _least_increments(lms, feats, dnis, keep, n, m)
                while bound > 0 and nis + max(lm_min[bound - 1], f_min[bound - 1]) > gate[k + bound]:
                    bound -= 1
                if bound > 0:
                    floor = nis + max(lm_min[bound - 1], f_min[bound - 1])
            if bound == 0 or k + bound < best_k or (k + bound == best_k and floor >= best_nis):
                lvl_done[level] = True
            else:
                counts = np.zeros(n, np.int64)
                for t in range(q):
                    if keep[t]:
                        counts[lms[t]] += 1
                jstar, fewest = -1, m + 1
                for j in range(n):
                    if counts[j] > 0 and counts[j] < fewest:
                        jstar, fewest = j, counts[j]
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
            dn, _ = append_pair(M, w, k * d, P, z, zhat, R, wrap, i, j)
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
