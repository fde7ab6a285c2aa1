"""The JCBB search, compiled: depth-first branch and bound with forward checking, iterative (a stack
of levels, one node each). The hypothesis keeps ``M = L⁻¹ P[J, :]`` for the landmarks in play and
their conditional moments ``c_j = Xᵀw``, ``G_j = XᵀX`` per hypothesis size ``k``
(``association.compatibility``), so a pairing's test is O(d³) whatever ``k`` and backtracking lowers
``k``. Per-node helpers are inlined: separate calls would count every array's references.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..association.compatibility import advance_moments, append_rows, take, whitened_nis


@njit(cache=True)
def make_work(n, m):
    """The bound's work arrays, once per search so no node allocates: (tag, seg, lm_min, f_min,
    f_val, f_stamp, f_list, match_l, match_f, match_stamp, parent, visit_l, visit_f, queue,
    group_min), views of one integer and one float buffer. Stamps replace clearing: an entry is set
    only where its stamp equals the current tag, which only grows."""
    ints = np.zeros(2 + 4 * n + 6 * m, np.int64)
    floats = np.empty(2 * n + 2 * m)
    tag, seg, f_stamp, f_list = ints[0:1], ints[1:n + 2], ints[n + 2:n + 2 + m], ints[n + 2 + m:n + 2 + 2 * m]
    at = n + 2 + 2 * m
    match_l, match_f, match_stamp = ints[at:at + n], ints[at + n:at + n + m], ints[at + n + m:at + n + 2 * m]
    at += n + 2 * m
    parent, visit_l, visit_f = ints[at:at + m], ints[at + m:at + m + n], ints[at + m + n:at + 2 * m + n]
    at += 2 * m + n
    queue = ints[at:at + n]
    lm_min, f_min, f_val, group_min = floats[0:n], floats[n:n + m], floats[n + m:n + 2 * m], floats[n + 2 * m:]
    return (tag, seg, lm_min, f_min, f_val, f_stamp, f_list, match_l, match_f, match_stamp, parent, visit_l,
            visit_f, queue, group_min)


@njit(cache=True, inline="always")
def _next_tag(counter):
    """The next stamp of the bound's work arrays (``counter`` is ``make_work``'s ``tag``, one entry)."""
    counter[0] += 1
    return counter[0]


@njit(cache=True, inline="always")
def _groups(lms, q, seg):
    """Landmark groups of the pairs (``lms`` is grouped by landmark): group ``u`` is
    ``seg[u]:seg[u + 1]``; returns their number."""
    nl = 0
    for t in range(q):
        if t == 0 or lms[t] != lms[t - 1]:
            seg[nl] = t
            nl += 1
    seg[nl] = q
    return nl


@njit(cache=True, inline="always")
def _distinct_features(feats, q, work):
    tag = _next_tag(work[0])
    stamp = work[5]
    nf = 0
    for t in range(q):
        if stamp[feats[t]] != tag:
            stamp[feats[t]] = tag
            nf += 1
    return nf


@njit(cache=True, inline="always")
def _max_matching(feats, nl, work):
    """Size of a maximum matching of the landmark groups (``_groups``) with their features
    (augmenting paths, breadth first)."""
    seg, match_l, match_f, match_stamp, parent = work[1], work[7], work[8], work[9], work[10]
    visit_l, visit_f, queue = work[11], work[12], work[13]
    counter = work[0]
    owner = _next_tag(counter)         # match_f[f] is valid only where match_stamp[f] == owner
    match_l[:nl] = -1
    size = 0
    for root in range(nl):
        tag = _next_tag(counter)
        head, tail = 0, 1
        queue[0] = root
        visit_l[root] = tag
        found = -1
        while head < tail and found < 0:
            u = queue[head]
            head += 1
            for e in range(seg[u], seg[u + 1]):
                f = feats[e]
                if visit_f[f] == tag:
                    continue
                visit_f[f] = tag
                parent[f] = u
                if match_stamp[f] != owner:
                    found = f
                    break
                nxt = match_f[f]
                if visit_l[nxt] != tag:
                    visit_l[nxt] = tag
                    queue[tail] = nxt
                    tail += 1
        f = found
        while f >= 0:           # flip the augmenting path back to the root
            u = parent[f]
            prev = match_l[u]
            match_f[f], match_stamp[f] = u, owner
            match_l[u] = f
            f = prev
        size += int(found >= 0)
    return size


@njit(cache=True, inline="always")
def _group_minima(dnis, nl, work):
    """Least NIS increment of each landmark group (``_groups``), into ``work[14][:nl]``."""
    seg, group_min = work[1], work[14]
    for u in range(nl):
        least = dnis[seg[u]]
        for t in range(seg[u] + 1, seg[u + 1]):
            least = min(least, dnis[t])
        group_min[u] = least


@njit(cache=True, inline="always")
def _least_increments(feats, dnis, q, nl, work):
    """Least NIS increment of each landmark group and of each feature, each list sorted
    (``work[2][:nl]``, ``work[3][:nf]``; the groups' also unsorted in ``work[14]``); returns nf."""
    lm_min, f_min, f_val, f_stamp, f_list = work[2], work[3], work[4], work[5], work[6]
    _group_minima(dnis, nl, work)
    lm_min[:nl] = work[14][:nl]
    _sort_prefix(lm_min, nl)
    tag = _next_tag(work[0])
    nf = 0
    for t in range(q):
        f = feats[t]
        if f_stamp[f] != tag:
            f_stamp[f] = tag
            f_val[f] = dnis[t]
            f_list[nf] = f
            nf += 1
        elif dnis[t] < f_val[f]:
            f_val[f] = dnis[t]
    for a in range(nf):
        f_min[a] = f_val[f_list[a]]
    _sort_prefix(f_min, nf)
    return nf


SMALL_SORT = 32     # up to this length an insertion sort: numba's sort has a fixed setup cost


@njit(cache=True)
def _after(a, b):
    """Whether ``a`` sorts after ``b`` in numpy's order (NaN last)."""
    return a > b or (a != a and b == b)


@njit(cache=True, inline="always")
def _sort_prefix(values, count):
    """Sort ``values[:count]`` ascending, NaN last (as ``ndarray.sort``): insertion sort up to
    ``SMALL_SORT`` values (numba's sort has a setup cost a handful of values does not repay), the
    library's beyond."""
    if count > SMALL_SORT:
        values[:count].sort()
        return
    for t in range(1, count):
        x = values[t]
        pos = t
        while pos > 0 and _after(values[pos - 1], x):
            values[pos] = values[pos - 1]
            pos -= 1
        values[pos] = x


@njit(cache=True, inline="always")
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
                dnis[q] = whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
                q += 1
    return q


@njit(cache=True, inline="always")
def _compact(lms, feats, dnis, q, nis, limit):
    """Keep, in order, the pairings with ``nis + dnis <= limit``; returns how many."""
    kept = 0
    for t in range(q):
        if not nis + dnis[t] > limit:
            lms[kept], feats[kept], dnis[kept] = lms[t], feats[t], dnis[t]
            kept += 1
    return kept


@njit(cache=True, inline="always")
def _bound(lms, feats, dnis, q, nis, k, gate, best_k, work):
    """(q, b, floor, nl): the first ``q`` pairings (compacted in place, in ``nl`` landmark groups)
    can still join a jointly compatible completion, at most ``b`` more pairings can, and the final
    NIS is at least ``floor``; ``work[14][:nl]`` holds each group's least increment where ``b > 0``
    and ``k + b`` reaches ``best_k``."""
    seg = work[1]
    bound = -1
    while True:     # a pairing that breaks the loosest gate it could still face leaves the subtree
        nl = _groups(lms, q, seg)
        nb = min(nl, _distinct_features(feats, q, work))
        if nb == bound:
            break
        bound = nb
        kept = _compact(lms, feats, dnis, q, nis, gate[k + bound])
        if kept == q:   # nothing left: the groups and the bound stand (the next pass would find so)
            break
        q = kept
    floor = nis
    if bound > 0 and k + bound >= best_k:
        # the loop ended on the groups of the final q (``seg``, ``nl``), which _open_node reads too
        bound = _max_matching(feats, nl, work)
        # b more pairings use b distinct landmarks and b distinct features; the final NIS is at
        # least NIS(H + p) for each of its pairings p, so at least the b-th smallest of the
        # per-landmark (and per-feature) least increments. It must pass gate[k + b].
        _least_increments(feats, dnis, q, nl, work)
        lm_min, f_min = work[2], work[3]
        while bound > 0 and nis + max(lm_min[bound - 1], f_min[bound - 1]) > gate[k + bound]:
            bound -= 1
        if bound > 0:
            floor = nis + max(lm_min[bound - 1], f_min[bound - 1])
    return q, bound, floor, nl


@njit(cache=True, inline="always")
def _open_node(level, lms, feats, dnis, nl, nis, gate_next, work, remaining, lvl_cand, lvl_dnis, lvl_cols):
    """Set up a node's children: branch on the landmark with the fewest pairings (fail first), ties
    to the smallest least NIS increase (a dive stopped early has pinned the pose with its surest
    pairings); its candidates go to ``lvl_cand[level]`` by NIS increase. Returns (landmark,
    candidates, candidates keeping NIS ≤ ``gate_next``, landmarks in play)."""
    seg, group_min = work[1], work[14]
    pick, fewest, surest = -1, lms.shape[0] + 1, np.inf
    for u in range(nl):
        count, least = seg[u + 1] - seg[u], group_min[u]
        if count < fewest or (count == fewest and least < surest):
            pick, fewest, surest = u, count, least
    nc = 0
    for t in range(seg[pick], seg[pick + 1]):      # insertion sort: a handful of candidates
        pos = nc
        while pos > 0 and lvl_dnis[level, pos - 1] > dnis[t]:
            lvl_dnis[level, pos], lvl_cand[level, pos] = lvl_dnis[level, pos - 1], lvl_cand[level, pos - 1]
            pos -= 1
        lvl_dnis[level, pos], lvl_cand[level, pos] = dnis[t], feats[t]
        nc += 1
    n_jc = 0
    while n_jc < nc and nis + lvl_dnis[level, n_jc] <= gate_next:
        n_jc += 1
    remaining[level + 1, :] = False
    ncols = 0
    for u in range(nl):
        if u != pick:
            remaining[level + 1, lms[seg[u]]] = True
            lvl_cols[level, ncols] = lms[seg[u]]
            ncols += 1
    return lms[seg[pick]], nc, n_jc, ncols


@njit(cache=True, inline="always")
def _push(level, k, i, j, lvl_cols, lvl_ncols, P, z, zhat, R, wrap, Mt, w, C, G, pair_work):
    """Append pairing (i, j) to the hypothesis of size k; moments of size k + 1 for the landmarks in
    play below this level. Returns the NIS increase."""
    d = z.shape[1]
    kd = k * d
    S, y, L, w2 = pair_work
    dn = whitened_nis(P, z, zhat, R, wrap, i, j, C[k], G[k], S, y, L, w2)
    cols = lvl_cols[level, :lvl_ncols[level]]
    append_rows(Mt, w, kd, P, j, L, w2, cols)
    advance_moments(Mt, kd, w2, cols, C[k], G[k], C[k + 1], G[k + 1])
    return dn


@njit(cache=True)
def is_matching(ic):
    """Whether no landmark and no feature has two individually compatible partners in ``ic`` (m, n)."""
    for j in range(ic.shape[1]):
        if np.sum(ic[:, j]) > 1:
            return False
    for i in range(ic.shape[0]):
        if np.sum(ic[i]) > 1:
            return False
    return True


@njit(cache=True)
def _adjacency(ic):
    """(start (n + 1,), features): landmark ``j``'s compatible features, ascending, are
    ``features[start[j]:start[j + 1]]``."""
    m, n = ic.shape
    start = np.zeros(n + 1, np.int64)
    for j in range(n):
        count = 0
        for i in range(m):
            count += ic[i, j]
        start[j + 1] = start[j] + count
    feats = np.empty(start[n], np.int64)
    for j in range(n):
        e = start[j]
        for i in range(m):
            if ic[i, j]:
                feats[e] = i
                e += 1
    return start, feats


@njit(cache=True)
def _search_state(n, m, d, q):
    """Every array of ``jcbb_search`` from one float, one integer and one boolean buffer: the factor
    ``Mt``, ``w``, moments ``C``, ``G`` and ``nis_at`` per size (not cleared: a search reads only
    what it wrote, but for size 0); per level (``n + 2``) the landmark, candidates, increments,
    landmarks in play, bound, floor, next child and flags (cleared); current and best pairings,
    history, the forward check's pair lists and the work arrays."""
    levels, nd = n + 2, n * d
    f = np.empty(nd * nd + nd + (n + 1) * n * d * (1 + d) + n + 1 + levels * (m + 1) + 2 * n + 2 + q + 2 * d * (d + 1))
    Mt, at = take(f, 0, nd * nd)
    w, at = take(f, at, nd)
    C, at = take(f, at, (n + 1) * n * d)
    G, at = take(f, at, (n + 1) * n * d * d)
    nis_at, at = take(f, at, n + 1)
    lvl_dnis, at = take(f, at, levels * m)
    lvl_floor, at = take(f, at, levels)
    hist_nis, at = take(f, at, 2 * n + 2)
    dnis, at = take(f, at, q)
    S, at = take(f, at, d * d)
    y, at = take(f, at, d)
    L, at = take(f, at, d * d)
    w2, at = take(f, at, d)
    C, G = C.reshape((n + 1, n, d)), G.reshape((n + 1, n, d, d))
    C[0], G[0], nis_at[0], lvl_floor[:], hist_nis[:] = 0.0, 0.0, 0.0, 0.0, 0.0
    ints = np.zeros(8 * n + 4 + levels * (6 + m + n) + 2 * q, np.int64)
    pair_i, at = take(ints, 0, n)
    pair_j, at = take(ints, at, n)
    best_i, at = take(ints, at, n)
    best_j, at = take(ints, at, n)
    ints[:at] = -1                                              # pairings: none
    lvl_cand, at = take(ints, at, levels * m)
    lvl_cols, at = take(ints, at, levels * n)
    lvl_j, at = take(ints, at, levels)
    lvl_ncand, at = take(ints, at, levels)
    lvl_njc, at = take(ints, at, levels)
    lvl_next, at = take(ints, at, levels)
    lvl_ncols, at = take(ints, at, levels)
    lvl_bound, at = take(ints, at, levels)
    hist_nodes, at = take(ints, at, 2 * n + 2)
    hist_k, at = take(ints, at, 2 * n + 2)
    lms, at = take(ints, at, q)
    feats, at = take(ints, at, q)
    flags = np.zeros(m + levels * (n + 2), np.bool_)
    free, at = take(flags, 0, m)
    free[:] = True                                              # every feature free
    remaining, at = take(flags, at, levels * n)
    lvl_done, at = take(flags, at, levels)
    lvl_pushed, at = take(flags, at, levels)
    return (Mt.reshape((nd, nd)), w, C, G, nis_at, lvl_dnis.reshape((levels, m)), lvl_floor, hist_nis, dnis,
            (S.reshape((d, d)), y, L.reshape((d, d)), w2), pair_i, pair_j, lvl_cand.reshape((levels, m)), lvl_j,
            lvl_ncand, lvl_njc, lvl_next, lvl_cols.reshape((levels, n)), lvl_ncols, lvl_bound, best_i, best_j,
            hist_nodes, hist_k, lms, feats, free, remaining.reshape((levels, n)), lvl_done, lvl_pushed,
            make_work(n, m))


@njit(cache=True)
def jcbb_search(ic, P, z, zhat, R, wrap, gate, max_nodes, prefix_test, init_i, init_j, init_nis):
    """Depth-first branch and bound from the jointly compatible incumbent ``(init_i, init_j)``
    (joint NIS ``init_nis``). Returns (features, landmarks, nodes visited, timed out, history of
    ``(nodes, pairings, NIS)`` per improvement, the incumbent first). A search that did not time out
    has proven its answer optimal."""
    m, n = ic.shape
    d = z.shape[1]
    adj_start, adj_feat = _adjacency(ic)
    if max_nodes >= 1 and init_i.shape[0] == adj_start[n] and is_matching(ic):
        # the incumbent holds every individually compatible pairing and none shares a landmark or
        # a feature: it is the only hypothesis of its size and none is larger, so the root proves it
        return (init_i.copy(), init_j.copy(), 1, False, np.zeros(1, np.int64), np.full(1, init_i.shape[0]),
                np.full(1, init_nis))
    (Mt, w, C, G, nis_at, lvl_dnis, lvl_floor, hist_nis, dnis_buf, pair_work, pair_i, pair_j, lvl_cand, lvl_j,
     lvl_ncand, lvl_njc, lvl_next, lvl_cols, lvl_ncols, lvl_bound, best_i, best_j, hist_nodes, hist_k, lms_buf,
     feats_buf, free, remaining, lvl_done, lvl_pushed, bound_work) = _search_state(n, m, d, adj_start[n])
    for j in range(n):
        remaining[0, j] = adj_start[j + 1] > adj_start[j]
    best_k, best_nis = init_i.shape[0], init_nis
    best_i[:best_k] = init_i
    best_j[:best_k] = init_j
    hist_k[0], hist_nis[0] = best_k, best_nis
    n_hist = 1
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
                slot = min(n_hist, hist_k.shape[0] - 1)
                hist_nodes[slot], hist_k[slot], hist_nis[slot] = nodes, k, nis
                n_hist = slot + 1
            q = _forward_check(remaining[level], free, adj_start, adj_feat, P, z, zhat, R, wrap, C[k], G[k],
                               lms_buf, feats_buf, dnis_buf, pair_work)
            q, bound, floor, nl = _bound(lms_buf, feats_buf, dnis_buf, q, nis, k, gate, best_k, bound_work)
            if bound == 0 or k + bound < best_k or (k + bound == best_k and floor >= best_nis):
                lvl_done[level] = True
            else:
                jstar, nc, n_jc, ncols = _open_node(level, lms_buf, feats_buf, dnis_buf, nl, nis, gate[k + 1],
                                                    bound_work, remaining, lvl_cand, lvl_dnis, lvl_cols)
                lvl_ncand[level] = nc
                lvl_njc[level] = n_jc                        # children that stay jointly compatible
                lvl_ncols[level] = ncols
                lvl_bound[level], lvl_floor[level] = bound, floor
                lvl_j[level] = jstar
                lvl_next[level] = 0
                lvl_done[level] = False
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
        reach = k + lvl_bound[level]
        if slot > last or reach < best_k or (reach == best_k and lvl_floor[level] >= best_nis):
            # the node's own bound, against the incumbent its earlier children may have improved:
            # every completion below has at most `reach` pairings and, with that many, NIS >= floor
            lvl_done[level] = True
            level -= 1
            continue
        if slot == n_jc and k + lvl_ncols[level] < best_k:
            continue        # "unassociated": too few landmarks left in play to reach the incumbent
        if slot != n_jc:
            a = slot if slot < n_jc else slot - 1
            i, j = lvl_cand[level, a], lvl_j[level]
            dn = _push(level, k, i, j, lvl_cols, lvl_ncols, P, z, zhat, R, wrap, Mt, w, C, G, pair_work)
            pair_i[k], pair_j[k] = i, j
            nis_at[k + 1] = nis_at[k] + dn
            k += 1
            free[i] = False
            lvl_pushed[level] = True
        else:
            lvl_pushed[level] = False                    # the "unassociated" child
        level += 1
        entering = True
    return best_i[:best_k], best_j[:best_k], nodes, timed_out, hist_nodes[:n_hist], hist_k[:n_hist], hist_nis[:n_hist]
