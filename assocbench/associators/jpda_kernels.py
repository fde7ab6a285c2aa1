"""JPDA's compiled kernels: clusters of the gating graph, exact event enumeration, loopy BP. All
work on the gated pairs' log-weights ``logr[i, j] = log(P_D N_ij / (λ (1 - P_D P_G)))``: an event's
probability is ``∝ exp(Σ_{(i,j)∈θ} logr[i, j])``. Clusters (connected components of the gated
bipartite graph) are independent; each is a compressed adjacency by landmark (``off``, ``nbr``,
``lw``), in index order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

LOG_CLIP = 300.0   # BP works on exp(logr); |logr| is clipped here so no sum overflows (e^300 ≈ 1e130)


@njit(cache=True)
def _components(gated):
    """Component labels of every landmark (0..n-1) and feature (n..n+m-1), numbered by their lowest
    landmark, -1 without a gated pair; returns (labels, count)."""
    m, n = gated.shape
    label = np.full(n + m, -1, np.int64)
    queue = np.empty(n + m, np.int64)
    count = 0
    for start in range(n):
        if label[start] >= 0 or not gated[:, start].any():
            continue
        label[start] = count
        head, tail = 0, 1
        queue[0] = start
        while head < tail:
            v = queue[head]
            head += 1
            if v < n:
                for i in range(m):
                    if gated[i, v] and label[n + i] < 0:
                        label[n + i] = count
                        queue[tail] = n + i
                        tail += 1
            else:
                for j in range(n):
                    if gated[v - n, j] and label[j] < 0:
                        label[j] = count
                        queue[tail] = j
                        tail += 1
        count += 1
    return label, count


@njit(cache=True)
def _cluster(gated, logr, label, c):
    """Cluster ``c`` as (landmarks, features, off, nbr, lw): its global landmark and feature
    indices and the adjacency by local landmark."""
    m, n = gated.shape
    lms = np.flatnonzero(label[:n] == c)
    feats = np.flatnonzero(label[n:] == c)
    local = np.full(m, -1, np.int64)
    for a in range(feats.shape[0]):
        local[feats[a]] = a
    off = np.zeros(lms.shape[0] + 1, np.int64)
    for q in range(lms.shape[0]):
        off[q + 1] = off[q] + gated[:, lms[q]].sum()
    nbr = np.empty(off[-1], np.int64)
    lw = np.empty(off[-1])
    for q in range(lms.shape[0]):
        e = off[q]
        for i in range(m):
            if gated[i, lms[q]]:
                nbr[e], lw[e] = local[i], logr[i, lms[q]]
                e += 1
    return lms, feats, off, nbr, lw


@njit(cache=True)
def events_lower_bound(off, nbr, mf):
    """A lower bound on a cluster's joint events in O(|E|): give each feature to one of its
    landmarks (the least loaded); each landmark choosing independently between undetected and its
    given features is an event, so at least ``Π_q (1 + given_q)``, and at least ``1 + |E|``. Capped
    at 2^62."""
    nl = off.shape[0] - 1
    given = np.zeros(nl, np.int64)
    owner = np.full(mf, -1, np.int64)
    for q in range(nl):
        for e in range(off[q], off[q + 1]):
            a = nbr[e]
            if owner[a] < 0 or given[q] < given[owner[a]]:
                if owner[a] >= 0:
                    given[owner[a]] -= 1
                owner[a] = q
                given[q] += 1
    cap = np.int64(1) << 62
    bound = np.int64(1)
    for q in range(nl):
        bound = cap if bound > cap // (1 + given[q]) else bound * (1 + given[q])
    return max(bound, off[-1] + 1)


@njit(cache=True)
def count_events(off, nbr, mf, budget):
    """A cluster's number of joint events, or -1 past ``budget``: the enumeration's walk without
    weights, the last landmark's options counted at once."""
    nl = off.shape[0] - 1
    used = np.zeros(mf, np.bool_)
    nxt = np.empty(nl, np.int64)
    col = np.empty(nl, np.int64)
    count = 0
    k = 0
    nxt[0] = -1
    while k >= 0:
        if k == nl - 1:                   # the last landmark: count its options, back up
            count += 1
            for e in range(off[k], off[k + 1]):
                count += not used[nbr[e]]
            if count > budget:
                return -1
            k -= 1
            continue
        if nxt[k] > off[k]:
            used[col[k]] = False
        if nxt[k] == -1:
            nxt[k] = off[k]
            col[k] = mf
        else:
            e = nxt[k]
            while e < off[k + 1] and used[nbr[e]]:
                e += 1
            if e == off[k + 1]:
                k -= 1
                continue
            nxt[k] = e + 1
            used[nbr[e]] = True
            col[k] = nbr[e]
        k += 1
        nxt[k] = -1
    return count


@njit(cache=True)
def enumerate_events(off, nbr, lw, mf, budget, beta):
    """Exact marginals of one cluster by enumerating its events depth first (each landmark
    undetected or one free gated feature) into ``beta`` (nl, mf + 1), last column undetected. Sums
    are kept relative to the largest weight so far (log-sum-exp in one pass). Returns the events, or
    -1 past ``budget``."""
    nl = off.shape[0] - 1
    used = np.zeros(mf, np.bool_)
    nxt = np.empty(nl + 1, np.int64)      # next option of each level: -1 undetected, else an edge
    col = np.empty(nl, np.int64)          # the column chosen at each level
    partial = np.zeros(nl + 1)            # log-weight of the choices above each level
    beta[:] = 0.0
    total, top, count = 0.0, -np.inf, 0
    k = 0
    nxt[0] = -1
    while k >= 0:
        if k == nl:                       # a complete event
            count += 1
            if count > budget:
                return -1
            s = partial[nl]
            if s > top:
                scale = np.exp(top - s)
                beta *= scale
                total *= scale
                top = s
            wgt = np.exp(s - top)
            total += wgt
            for q in range(nl):
                beta[q, col[q]] += wgt
            k -= 1
            continue
        if nxt[k] > off[k]:
            used[col[k]] = False          # back from below a pairing: its feature is free again
        if nxt[k] == -1:
            nxt[k] = off[k]
            col[k] = mf
            partial[k + 1] = partial[k]
        else:
            e = nxt[k]
            while e < off[k + 1] and used[nbr[e]]:
                e += 1
            if e == off[k + 1]:
                k -= 1                    # options exhausted: back up
                continue
            nxt[k] = e + 1
            used[nbr[e]] = True
            col[k] = nbr[e]
            partial[k + 1] = partial[k] + lw[e]
        k += 1
        nxt[k] = -1
    beta /= total
    return count


@njit(cache=True)
def _by_feature(off, nbr, mf):
    """The cluster's edges grouped by feature: (foff, fedge) with feature ``a``'s edge ids in
    ``fedge[foff[a]:foff[a + 1]]``, in landmark order."""
    foff = np.zeros(mf + 1, np.int64)
    for e in range(nbr.shape[0]):
        foff[nbr[e] + 1] += 1
    for a in range(mf):
        foff[a + 1] += foff[a]
    fill = foff[:-1].copy()
    fedge = np.empty(nbr.shape[0], np.int64)
    for e in range(nbr.shape[0]):
        fedge[fill[nbr[e]]] = e
        fill[nbr[e]] += 1
    return foff, fedge


@njit(cache=True)
def _leave_one_out(vals, ids, start, stop, out):
    """``out[ids[t]] = 1 + Σ_{s≠t} vals[ids[s]]`` over ``t`` in start..stop-1, by prefix and
    suffix sums (no subtraction of a large term from a large sum)."""
    acc = 1.0
    for t in range(start, stop):
        out[ids[t]] = acc
        acc += vals[ids[t]]
    acc = 0.0
    for t in range(stop - 1, start - 1, -1):
        out[ids[t]] += acc
        acc += vals[ids[t]]


@njit(cache=True)
def belief_propagation(off, nbr, lw, mf, tol, max_iter, beta):
    """Approximate marginals of one cluster by loopy BP on the assignment problem (Williams & Lau
    2014) into ``beta`` (nl, mf + 1). With ``w_e = exp(lw_e)`` per gated edge ``e = (q, a)``:

        μ_e = w_e / (1 + Σ_{e'∋q, e'≠e} w_e' ν_e'),   ν_e = 1 / (1 + Σ_{e'∋a, e'≠e} μ_e'),

    from ``ν = 1`` until ``max |Δν| <= tol`` (or ``max_iter``); then ``β_qa = w_e ν_e / D_q``,
    ``β_q∅ = 1 / D_q``, ``D_q = 1 + Σ_{e∋q} w_e ν_e``. Exact on a tree. Returns the sweeps."""
    nl = off.shape[0] - 1
    ne = nbr.shape[0]
    w = np.exp(np.minimum(np.maximum(lw, -LOG_CLIP), LOG_CLIP))
    foff, fedge = _by_feature(off, nbr, mf)
    ledge = np.arange(ne)
    nu = np.ones(ne)
    mu = np.empty(ne)
    wnu = np.empty(ne)
    den = np.empty(ne)
    sweeps = 0
    for sweeps in range(1, max_iter + 1):  # noqa: B007 - the count of sweeps run is returned
        for e in range(ne):
            wnu[e] = w[e] * nu[e]
        for q in range(nl):
            _leave_one_out(wnu, ledge, off[q], off[q + 1], den)
        for e in range(ne):
            mu[e] = w[e] / den[e]
        for a in range(mf):
            _leave_one_out(mu, fedge, foff[a], foff[a + 1], den)
        change = 0.0
        for e in range(ne):
            new = 1.0 / den[e]
            change = max(change, abs(new - nu[e]))
            nu[e] = new
        if change <= tol:
            break
    beta[:] = 0.0
    for q in range(nl):
        norm = 1.0
        for e in range(off[q], off[q + 1]):
            norm += w[e] * nu[e]
        for e in range(off[q], off[q + 1]):
            beta[q, nbr[e]] = w[e] * nu[e] / norm
        beta[q, mf] = 1.0 / norm
    return sweeps


@njit(cache=True)
def jpda_marginals(gated, logr, max_events, tol, max_iter):
    """``β`` (n, m + 1) (last column undetected), per cluster: enumerated up to ``max_events``
    events, loopy BP beyond. Returns (β, events, clusters, approximate clusters, largest cluster,
    most BP sweeps)."""
    m, n = gated.shape
    beta = np.zeros((n, m + 1))
    beta[:, m] = 1.0                      # a landmark with no gated feature is surely undetected
    label, count = _components(gated)
    events, approx, largest, sweeps = 0, 0, 0, 0
    for c in range(count):
        lms, feats, off, nbr, lw = _cluster(gated, logr, label, c)
        nl, mf = lms.shape[0], feats.shape[0]
        largest = max(largest, nl)
        local = np.empty((nl, mf + 1))
        got = -1
        if events_lower_bound(off, nbr, mf) <= max_events and count_events(off, nbr, mf, max_events) >= 0:
            got = enumerate_events(off, nbr, lw, mf, max_events, local)
        if got >= 0:
            events += got
        else:
            approx += 1
            sweeps = max(sweeps, belief_propagation(off, nbr, lw, mf, tol, max_iter, local))
        for q in range(nl):
            beta[lms[q], m] = local[q, mf]
            for a in range(mf):
                beta[lms[q], feats[a]] = local[q, a]
    return beta, events, count, approx, largest, sweeps
