"""The compatibility math, in one place: every associator and the scorer call these.

Notation (lab 8, eqs. 11-17): feature ``i`` measures ``z_i`` with noise ``R_i``; candidate ``j``
predicts ``zhat_j``; the joint predicted covariance is ``P``. For a hypothesis pairing landmarks
``J`` with features ``I``

    y_A = wrap(z_I - zhat_J),   S_A = P[J, J] + blockdiag(R_I) = L Lᵀ,   L w = y_A,
    NIS(A) = wᵀw,   log N(y_A; 0, S_A) = -½ (wᵀw + log det S_A + d|A| log 2π).

Individual compatibility is ``NIS({(i, j)}) <= χ²_d(c)``, joint ``NIS(A) <= χ²_{d|A|}(c)``; the
binary constraint tests the difference of two innovations (``difference_nis``). Total surprisal
``s(A) = n_U log|Y| - log N(y_A; 0, S_A)``, ``n_U = n - |A|``. Cholesky factors and triangular
solves throughout; no explicit inverse.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit
from scipy.stats import chi2

from .problem import Problem, pairs_of

LOG_2PI = float(np.log(2 * np.pi))


@lru_cache(maxsize=1024)
def joint_gates(d: int, n: int, confidence: float) -> np.ndarray:
    """``gate[k] = χ²_{dk}(c)`` for k = 0..n pairings (``gate[0] = 0``); read-only, cached per (d,
    n, c)."""
    gates = np.array([chi2_threshold(d * k, confidence) for k in range(n + 1)])
    gates.flags.writeable = False
    return gates


@lru_cache(maxsize=4096)
def chi2_threshold(dof: int, confidence: float) -> float:
    """Gate ``χ²_dof(c)``: the ``confidence`` quantile of a χ² variable with ``dof`` degrees."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    return float(chi2.ppf(confidence, dof)) if dof > 0 else 0.0


def wrap_angles(residual: np.ndarray, angular: tuple[int, ...]) -> np.ndarray:
    """Wrap the ``angular`` dims (last axis) of a residual into [-π, π)."""
    if not angular:
        return residual
    out = np.array(residual, dtype=np.float64, copy=True)
    idx = list(angular)
    out[..., idx] = (out[..., idx] + np.pi) % (2 * np.pi) - np.pi
    return out


def innovations(problem: Problem) -> np.ndarray:
    """All pairwise innovations ``y_ij = wrap(z_i - zhat_j)``, shape (m, n, d)."""
    return wrap_angles(problem.z[:, None, :] - problem.zhat[None, :, :], problem.angular)


def marginal_blocks(problem: Problem) -> np.ndarray:
    """The diagonal (d, d) blocks ``P_jj`` of the prediction covariance, shape (n, d, d)."""
    n, d = problem.n, problem.d
    blocks = problem.P.reshape(n, d, n, d)
    return blocks[np.arange(n), :, np.arange(n), :]


def log_gaussian(nis: np.ndarray | float, logdet: np.ndarray | float, dim: int) -> np.ndarray | float:
    """``log N = -½ (NIS + log det S + dim·log 2π)``."""
    return -0.5 * (nis + logdet + dim * LOG_2PI)


def pairwise_nis(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Individual NIS ``y_ijᵀ S_ij⁻¹ y_ij``, ``S_ij = P_jj + R_i``, and ``log det S_ij``, (m, n)
    each: ``whitened_pair`` from the empty hypothesis over every pair.
    """
    m, n = problem.m, problem.n
    if m == 0 or n == 0:
        return np.zeros((m, n)), np.zeros((m, n))
    feats, lms = (a.ravel() for a in np.indices((m, n)))
    nis, logdet = _individual_terms(problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem), lms, feats)
    return nis.reshape(m, n), logdet.reshape(m, n)


def pairwise_log_likelihood(problem: Problem) -> np.ndarray:
    """``log N(z_i; zhat_j, P_jj + R_i)`` for every feature/landmark pair, (m, n)."""
    nis, logdet = pairwise_nis(problem)
    return log_gaussian(nis, logdet, problem.d)


def individually_compatible(problem: Problem, confidence: float = 0.99,
                            nis: np.ndarray | None = None) -> np.ndarray:
    """Mask (m, n) of pairs with ``NIS_ij <= χ²_d(c)`` (eq. 12); without ``nis``, from
    ``gated_pairs`` (the same mask bit for bit)."""
    if nis is not None:
        return nis <= chi2_threshold(problem.d, confidence)
    return gate_mask(problem, confidence)[0]


def gate_mask(problem: Problem, confidence: float = 0.99) -> tuple[np.ndarray, np.ndarray]:
    """``individually_compatible``'s mask and the landmarks with a pair in the gate (ascending), in
    one compiled pass."""
    if problem.m == 0 or problem.n == 0:
        return np.zeros((problem.m, problem.n), np.bool_), np.zeros(0, np.int64)
    return gate_mask_kernel(problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem),
                            chi2_threshold(problem.d, confidence))


def gated_pairs(problem: Problem, confidence: float = 0.99) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs with ``NIS_ij <= χ²_d(c)``: (features, landmarks, NIS, log det S_ij), by landmark
    then feature."""
    return pairs_within(problem, chi2_threshold(problem.d, confidence))


def pairs_within(problem: Problem, limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every pair with ``NIS_ij = y_ijᵀ (P_jj + R_i)⁻¹ y_ij <= limit``: (features, landmarks, NIS,
    log det), by landmark then feature, ``pairwise_nis``'s values bit for bit.

    Output-sensitive and exact (``_sweep_gate``): for a unit vector ``e``,
    ``yᵀS⁻¹y >= (eᵀy)² / eᵀSe`` (Cauchy-Schwarz), so a pair in the gate has
    ``y_a² <= limit · (P_jj + R̄)_aa`` in every dimension, ``R̄_aa = max_i (R_i)_aa``. With the
    features sorted along one axis (on the circle where it wraps), each landmark's candidates are
    found by two binary searches, then boxed in every dimension, then whitened."""
    m, n = problem.m, problem.n
    if m == 0 or n == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0), np.zeros(0)
    return _sweep_gate(problem.P, problem.z, problem.zhat, problem.R, wrap_mask(problem), float(limit))


def pair_innovations(problem: Problem, feats: np.ndarray, lms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``y_ij = wrap(z_i - zhat_j)`` (k, d) and ``S_ij = P_jj + R_i`` (k, d, d) of the listed pairs."""
    y = wrap_angles(problem.z[feats] - problem.zhat[lms], problem.angular)
    return y, marginal_blocks(problem)[lms] + problem.R[feats]


def stacked_nis(y: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``yᵀ S⁻¹ y`` of stacks (k, d), (k, d, d): ``S = L Lᵀ``, ``L w = y``, ``NIS = wᵀw``."""
    L = np.linalg.cholesky(S)
    w = np.empty_like(y)
    for a in range(y.shape[1]):
        w[:, a] = (y[:, a] - np.einsum("kb,kb->k", L[:, a, :a], w[:, :a])) / L[:, a, a]
    return np.einsum("ka,ka->k", w, w)


def joint_terms(problem: Problem, association: np.ndarray) -> tuple[float, float, int]:
    """``(NIS(A), log det S_A, |A|)`` of a whole hypothesis, grown pairing by pairing."""
    factor = JointFactor(problem)
    for j, i in zip(*pairs_of(np.asarray(association))):
        factor.push(i, j)
    return factor.nis, factor.logdet, factor.k


def joint_nis(problem: Problem, association: np.ndarray) -> float:
    """Joint NIS of a hypothesis (eq. 16-17)."""
    return joint_terms(problem, association)[0]


def joint_verdict(problem: Problem, association: np.ndarray, confidence: float = 0.99) -> tuple[float, bool]:
    """Total surprisal and joint compatibility from one evaluation of the joint terms."""
    nis, logdet, k = joint_terms(problem, association)
    s = (problem.n - k) * float(np.log(problem.volume)) - float(log_gaussian(nis, logdet, problem.d * k))
    return s, bool(k == 0 or nis <= chi2_threshold(problem.d * k, confidence))


def jointly_compatible(problem: Problem, association: np.ndarray, confidence: float = 0.99) -> bool:
    """Whether ``NIS(A) <= χ²_{d|A|}(c)`` (eq. 15); the empty hypothesis is compatible."""
    return joint_verdict(problem, association, confidence)[1]


def surprisal(problem: Problem, association: np.ndarray) -> float:
    """``s(A) = n_U log|Y| - log N(y_A; 0, S_A)`` (lab 8, section 2), ``n_U`` the unassociated
    candidates."""
    return joint_verdict(problem, association)[0]


# -- the incremental joint factor, compiled ---------------------------------------------------
# These kernels are the only implementation of the incremental joint test: ``JointFactor``
# (the scorer's joint terms), the SNN greedy and the JCBB search all call them. The factor
# keeps ``M = L⁻¹ P[J, :]`` stored transposed, ``Mt = Mᵀ`` (row ``l·d + b`` of ``Mt`` is
# column ``l·d + b`` of ``M``, so what a test reads about one landmark is contiguous), and
# ``w = L⁻¹ y_A``; ``kd`` entries of each row are in use. What a hypothesis says about landmark
# ``j`` is summarised by its conditional moments ``c_j = Xᵀw`` and ``G_j = XᵀX`` with
# ``X = M[:kd, j]`` (the shift of its predicted innovation and the covariance its prediction
# loses); a pairing's test needs nothing else.


@njit(cache=True, inline="always")
def _dot_rows(A, ra, B, rb, length):
    """``Σ_r<length A[ra, r] B[rb, r]`` in four interleaved partial sums, in a fixed order
    (machine-independent)."""
    s0, s1, s2, s3 = 0.0, 0.0, 0.0, 0.0
    top = length - length % 4
    for r in range(0, top, 4):
        s0 += A[ra, r] * B[rb, r]
        s1 += A[ra, r + 1] * B[rb, r + 1]
        s2 += A[ra, r + 2] * B[rb, r + 2]
        s3 += A[ra, r + 3] * B[rb, r + 3]
    for r in range(top, length):
        s0 += A[ra, r] * B[rb, r]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, inline="always")
def _cross_block(Mt, j, l, kd, d, out):
    """``out[a, b] = Σ_r<kd Mt[j·d + a, r] Mt[l·d + b, r]``: the (d, d) block ``X_jᵀ X_l``
    (``_cross_block_2`` for d = 2)."""
    if d != 2:
        for a in range(d):
            for b in range(d):
                out[a, b] = _dot_rows(Mt, j * d + a, Mt, l * d + b, kd)
        return
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = _cross_block_2(Mt, j, l, kd)


@njit(cache=True, inline="always")
def _cross_block_2(Mt, j, l, kd):
    """``_cross_block`` for d = 2 as four scalars: shared loads, eight interleaved chains, fixed
    order."""
    ja, la = 2 * j, 2 * l
    s00, s01, s10, s11 = 0.0, 0.0, 0.0, 0.0
    u00, u01, u10, u11 = 0.0, 0.0, 0.0, 0.0
    top = kd - kd % 2
    for r in range(0, top, 2):
        a0, a1, b0, b1 = Mt[ja, r], Mt[ja + 1, r], Mt[la, r], Mt[la + 1, r]
        s00 += a0 * b0
        s01 += a0 * b1
        s10 += a1 * b0
        s11 += a1 * b1
        a0, a1, b0, b1 = Mt[ja, r + 1], Mt[ja + 1, r + 1], Mt[la, r + 1], Mt[la + 1, r + 1]
        u00 += a0 * b0
        u01 += a0 * b1
        u10 += a1 * b0
        u11 += a1 * b1
    if top < kd:
        a0, a1, b0, b1 = Mt[ja, top], Mt[ja + 1, top], Mt[la, top], Mt[la + 1, top]
        s00 += a0 * b0
        s01 += a0 * b1
        s10 += a1 * b0
        s11 += a1 * b1
    return s00 + u00, s01 + u01, s10 + u10, s11 + u11


@njit(cache=True)
def conditional_moments(Mt, w, kd, j, c_out, G_out):
    """``c_j = Xᵀw`` (d,) and ``G_j = XᵀX`` (d, d) with ``X = M[:kd, j]``, into the outputs."""
    d = c_out.shape[0]
    for a in range(d):
        acc = 0.0
        for r in range(kd):
            acc += Mt[j * d + a, r] * w[r]
        c_out[a] = acc
        for b in range(d):
            G_out[a, b] = _dot_rows(Mt, j * d + a, Mt, j * d + b, kd)


@njit(cache=True, inline="always")
def _residual(z, zhat, wrap, i, j, a):
    """``z_i - zhat_j`` in dimension ``a``, wrapped into [-π, π) where the dimension is angular."""
    acc = z[i, a] - zhat[j, a]
    if wrap[a] and (acc >= np.pi or acc < -np.pi):
        acc -= 2.0 * np.pi * np.floor((acc + np.pi) / (2.0 * np.pi))
    return acc


TWO_PI = 2.0 * np.pi


@njit(cache=True, inline="always")
def _on_circle(x):
    """``x`` mod 2π, in [0, 2π)."""
    r = x - TWO_PI * np.floor(x / TWO_PI)
    return r if r < TWO_PI else 0.0


@njit(cache=True)
def _sweep_axis(P, z, zhat, wrap, r_max, limit):
    """The dimension whose gate windows hold the fewest features, ``Σ_j min(1, 2 h_ja / span_a)``."""
    m, d = z.shape
    n = zhat.shape[0]
    best, best_cost = 0, np.inf
    for a in range(d):
        if wrap[a]:
            span = TWO_PI
        else:
            lo, hi = z[0, a], z[0, a]
            for i in range(1, m):
                lo, hi = min(lo, z[i, a]), max(hi, z[i, a])
            span = hi - lo
        cost = 0.0
        for j in range(n):
            width = 2.0 * np.sqrt(limit * (P[j * d + a, j * d + a] + r_max[a]))
            cost += 1.0 if not width < span else width / span
        if cost < best_cost:
            best, best_cost = a, cost
    return best


@njit(cache=True, inline="always")
def _inside_box(P, z, zhat, R, wrap, i, j, limit):
    """Whether ``y_a² <= limit · (P_jj + R_i)_aa`` in every dimension ``a``."""
    d = z.shape[1]
    for a in range(d):
        y = _residual(z, zhat, wrap, i, j, a)
        if y * y > limit * (P[j * d + a, j * d + a] + R[i, a, a]):
            return False
    return True


@njit(cache=True)
def _window(keys, lo, hi, wrapped):
    """Index ranges ``[(s0, e0), (s1, e1)]`` of sorted ``keys`` in ``[lo, hi]`` (two where a wrapped
    window runs over 0 or 2π)."""
    if not wrapped:
        return np.searchsorted(keys, lo), np.searchsorted(keys, hi, side="right"), 0, 0
    if hi - lo >= TWO_PI:
        return 0, keys.shape[0], 0, 0
    if lo < 0.0:
        return 0, np.searchsorted(keys, hi, side="right"), np.searchsorted(keys, lo + TWO_PI), keys.shape[0]
    if hi >= TWO_PI:
        return np.searchsorted(keys, lo), keys.shape[0], 0, np.searchsorted(keys, hi - TWO_PI, side="right")
    return np.searchsorted(keys, lo), np.searchsorted(keys, hi, side="right"), 0, 0


@njit(cache=True, inline="always")
def take(buffer, at, size):
    """(``buffer[at:at + size]``, the next offset): work arrays carved from one allocation."""
    return buffer[at:at + size], at + size


@njit(cache=True, inline="always")
def _argsort_into(keys, order, sorted_keys):
    """``order = argsort(keys)`` and ``sorted_keys``, by insertion up to 32 keys, the library's
    beyond; ties in any order."""
    m = keys.shape[0]
    if m > 32:
        order[:] = np.argsort(keys)
        for t in range(m):
            sorted_keys[t] = keys[order[t]]
        return
    for t in range(m):
        x = keys[t]
        pos = t
        while pos > 0 and sorted_keys[pos - 1] > x:
            sorted_keys[pos], order[pos] = sorted_keys[pos - 1], order[pos - 1]
            pos -= 1
        sorted_keys[pos], order[pos] = x, t


@njit(cache=True, inline="always")
def _sort_small(values, count):
    """Sort ``values[:count]`` (integers) in place: by insertion up to 32 (a gate window holds a
    handful, where the library sort's setup dominates), the library's beyond."""
    if count > 32:
        values[:count].sort()
        return
    for t in range(1, count):
        x = values[t]
        pos = t
        while pos > 0 and values[pos - 1] > x:
            values[pos] = values[pos - 1]
            pos -= 1
        values[pos] = x


@njit(cache=True)
def _sweep_gate(P, z, zhat, R, wrap, limit, with_logdet=True):
    """``pairs_within``'s pairs (log det 0 unless ``with_logdet``). The box is a hair loose
    (``limit · (1 + 1e-6)``) and the windows looser still, so no pair of the box is missed; the NIS
    decides."""
    m, d = z.shape
    n = zhat.shape[0]
    box = limit * (1.0 + 1e-6)
    # one float and one integer buffer for every work array, and one of each for the outputs
    # (4 allocations instead of 15)
    work = np.empty(d + 2 * m + n * d * (d + 1) + 2 * d * (d + 1))
    r_max, at = take(work, 0, d)
    keys, at = take(work, at, m)
    sorted_keys, at = take(work, at, m)
    C, at = take(work, at, n * d)
    G, at = take(work, at, n * d * d)
    r_max[:], C[:], G[:] = 0.0, 0.0, 0.0           # the empty hypothesis: zero moments, as pairwise_nis
    C, G = C.reshape((n, d)), G.reshape((n, d, d))
    S, at = take(work, at, d * d)
    y, at = take(work, at, d)
    L, at = take(work, at, d * d)
    w2, at = take(work, at, d)
    S, L = S.reshape((d, d)), L.reshape((d, d))
    for i in range(m):
        for a in range(d):
            r_max[a] = max(r_max[a], R[i, a, a])
    s = _sweep_axis(P, z, zhat, wrap, r_max, box)
    wrapped = wrap[s]
    reach = 0.0                                   # the keys' magnitude, for their rounding
    for i in range(m):
        keys[i] = _on_circle(z[i, s]) if wrapped else z[i, s]
        reach = max(reach, abs(z[i, s]))
    index = np.empty(2 * m, np.int64)
    order, cand = index[:m], index[m:]
    _argsort_into(keys, order, sorted_keys)
    keys = sorted_keys
    cap = 4 * (m + n)
    pairs, values = np.empty(2 * cap, np.int64), np.empty(2 * cap)
    feats, lms, nis, logdet = pairs[:cap], pairs[cap:], values[:cap], values[cap:]
    q = 0
    for j in range(n):
        half = np.sqrt(box * (P[j * d + s, j * d + s] + r_max[s]))
        centre = _on_circle(zhat[j, s]) if wrapped else zhat[j, s]
        half += 1e-9 * half + 1e-12 * (reach + abs(zhat[j, s]) + TWO_PI)
        s0, e0, s1, e1 = _window(keys, centre - half, centre + half, wrapped)
        count = 0
        for t in range(s0, e0):
            if _inside_box(P, z, zhat, R, wrap, order[t], j, box):
                cand[count] = order[t]
                count += 1
        for t in range(s1, e1):
            if _inside_box(P, z, zhat, R, wrap, order[t], j, box):
                cand[count] = order[t]
                count += 1
        _sort_small(cand, count)
        if q + count > cap:
            cap = max(2 * cap, q + count)
            feats, lms, nis, logdet = _grown(feats, q, cap), _grown(lms, q, cap), _grown(nis, q, cap), _grown(logdet, q, cap)
        for t in range(count):
            i = cand[t]
            v, det = _individual_whitened(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2)
            if v <= limit:
                feats[q], lms[q], nis[q], logdet[q] = i, j, v, np.log(det) if with_logdet else 0.0
                q += 1
    return feats[:q], lms[:q], nis[:q], logdet[:q]


@njit(cache=True, inline="always")
def _individual_whitened(P, z, zhat, R, wrap, i, j, C, G, S, y, L, w2):
    """(NIS, det S) of pairing (i, j) given moments ``C``, ``G``: ``whitened_pair``'s arithmetic,
    scalars for d = 2."""
    if z.shape[1] == 2:
        return _whitened_nis_2(P, z, zhat, R, wrap, i, j, C, G, L, w2)
    pair_innovation(P, z, zhat, R, wrap, i, j, C, G, S, y)
    return _whiten_det(S, y, L, w2)


@njit(cache=True)
def pairs_within_kernel(P, z, zhat, R, wrap, limit, with_logdet):
    """``pairs_within`` callable from compiled code, so a method that gates and decides in one call
    (MNN) hands no pair list to Python."""
    return _sweep_gate(P, z, zhat, R, wrap, limit, with_logdet)


@njit(cache=True)
def gate_mask_kernel(P, z, zhat, R, wrap, limit):
    """``gate_mask`` on the problem's arrays, ``limit = χ²_d(c)``: callable from compiled code."""
    feats, lms, _, _ = _sweep_gate(P, z, zhat, R, wrap, limit, False)
    mask = np.zeros((z.shape[0], zhat.shape[0]), np.bool_)
    candidates = np.empty(lms.shape[0], np.int64)
    count = 0
    for t in range(lms.shape[0]):           # lms ascending
        mask[feats[t], lms[t]] = True
        if t == 0 or lms[t] != lms[t - 1]:
            candidates[count] = lms[t]
            count += 1
    return mask, candidates[:count]


@njit(cache=True)
def _grown(arr, used, cap):
    out = np.empty(cap, arr.dtype)
    out[:used] = arr[:used]
    return out


@njit(cache=True, inline="always")
def pair_innovation(P, z, zhat, R, wrap, i, j, C, G, S_out, y_out):
    """Conditional innovation of (i, j) given moments ``C[j] = c_j``, ``G[j] = G_j``:
    ``S = P_jj + R_i - G_j``, ``y = wrap(z_i - zhat_j) - c_j``."""
    d = z.shape[1]
    for a in range(d):
        y_out[a] = _residual(z, zhat, wrap, i, j, a) - C[j, a]
        for b in range(d):
            S_out[a, b] = P[j * d + a, j * d + b] + R[i, a, b] - G[j, a, b]


@njit(cache=True, inline="always")
def _whiten(S, y, L_out, w_out):
    """Cholesky ``S = L Lᵀ`` and ``w = L⁻¹ y`` into the outputs; returns (wᵀw, log det S), (inf,
    inf) when not definite."""
    nis, det = _whiten_det(S, y, L_out, w_out)
    return nis, np.log(det)  # det S = Π L_aa², one log instead of d


@njit(cache=True, inline="always")
def _whiten_det(S, y, L_out, w_out):
    """``_whiten`` with ``det S`` instead of its log: the searches need only the NIS and skip the
    log."""
    d = S.shape[0]
    det = 1.0
    for a in range(d):
        for b in range(a + 1):
            acc = S[a, b]
            for c in range(b):
                acc -= L_out[a, c] * L_out[b, c]
            if a == b:
                if acc <= 0.0:
                    return np.inf, np.inf
                L_out[a, a] = np.sqrt(acc)
                det *= acc
            else:
                L_out[a, b] = acc / L_out[b, b]
        for b in range(a + 1, d):
            L_out[a, b] = 0.0
    nis = 0.0
    for a in range(d):
        acc = y[a]
        for c in range(a):
            acc -= L_out[a, c] * w_out[c]
        w_out[a] = acc / L_out[a, a]
        nis += w_out[a] * w_out[a]
    return nis, det


@njit(cache=True, inline="always")
def whitened_pair(P, z, zhat, R, wrap, i, j, C, G, S, y, L_out, w_out):
    """(ΔNIS, Δlog det) of adding (i, j): ``|L22⁻¹ y|²``, ``L22 L22ᵀ = S`` (``pair_innovation``);
    ``L22``, ``L22⁻¹ y`` into the outputs."""
    pair_innovation(P, z, zhat, R, wrap, i, j, C, G, S, y)
    return _whiten(S, y, L_out, w_out)


@njit(cache=True, inline="always")
def whitened_nis(P, z, zhat, R, wrap, i, j, C, G, S, y, L_out, w_out):
    """``whitened_pair``'s ΔNIS alone, bit for bit."""
    if z.shape[1] == 2:         # the planar, line and camera tracks' case, in scalars
        return _whitened_nis_2(P, z, zhat, R, wrap, i, j, C, G, L_out, w_out)[0]
    pair_innovation(P, z, zhat, R, wrap, i, j, C, G, S, y)
    return _whiten_det(S, y, L_out, w_out)[0]


@njit(cache=True, inline="always")
def _whitened_nis_2(P, z, zhat, R, wrap, i, j, C, G, L_out, w_out):
    """``pair_innovation`` then ``_whiten_det`` for d = 2 in scalars, their arithmetic in their
    order (bit for bit, same outputs): no work-array stores and reloads in the inner loop of JCBB
    and the gate."""
    y0 = _residual(z, zhat, wrap, i, j, 0) - C[j, 0]
    y1 = _residual(z, zhat, wrap, i, j, 1) - C[j, 1]
    s00 = P[2 * j, 2 * j] + R[i, 0, 0] - G[j, 0, 0]
    s10 = P[2 * j + 1, 2 * j] + R[i, 1, 0] - G[j, 1, 0]
    s11 = P[2 * j + 1, 2 * j + 1] + R[i, 1, 1] - G[j, 1, 1]
    if s00 <= 0.0:
        return np.inf, np.inf
    l00 = np.sqrt(s00)
    l10 = s10 / l00
    L_out[0, 0], L_out[0, 1], L_out[1, 0] = l00, 0.0, l10
    pivot = s11 - l10 * l10
    if pivot <= 0.0:
        return np.inf, np.inf
    l11 = np.sqrt(pivot)
    L_out[1, 1] = l11
    w0 = y0 / l00
    w1 = (y1 - l10 * w0) / l11
    w_out[0], w_out[1] = w0, w1
    return w0 * w0 + w1 * w1, s00 * pivot     # _whiten_det's det: (1.0 · s00) · pivot


@njit(cache=True, inline="always")
def _ldl_nis(S, y):
    """``yᵀ S⁻¹ y`` by ``S = L D Lᵀ`` (unit ``L`` in ``S``'s strict lower triangle, ``D`` on its
    diagonal): ``u = L⁻¹ y``, ``Σ u_a² / D_a``; overwrites both, inf when not definite. No square
    root or log."""
    d = S.shape[0]
    nis = 0.0
    for a in range(d):
        for b in range(a):
            acc = S[a, b]
            for c in range(b):
                acc -= S[a, c] * S[c, c] * S[b, c]
            S[a, b] = acc / S[b, b]
        piv = S[a, a]
        u = y[a]
        for c in range(a):
            piv -= S[a, c] * S[a, c] * S[c, c]
            u -= S[a, c] * y[c]
        if not piv > 0.0:
            return np.inf
        S[a, a] = piv
        y[a] = u
        nis += u * u / piv
    return nis


@njit(cache=True, inline="always")
def difference_nis_kernel(P, Pd, z, zhat, R, wrap, i, j, i2, j2, S, y):
    """``difference_nis`` of (i, j) and (i2, j2) with ``Pd`` (``marginal_blocks``) and work arrays;
    inf when not definite. ``P_j'j = P_jj'ᵀ`` is read along landmark j's rows."""
    d = z.shape[1]
    for a in range(d):
        acc = (z[i, a] - zhat[j, a]) - (z[i2, a] - zhat[j2, a])
        if wrap[a] and (acc >= np.pi or acc < -np.pi):
            acc -= 2.0 * np.pi * np.floor((acc + np.pi) / (2.0 * np.pi))
        y[a] = acc
        for b in range(d):
            S[a, b] = (Pd[j, a, b] + Pd[j2, a, b] - P[j * d + a, j2 * d + b] - P[j * d + b, j2 * d + a]
                       + R[i, a, b] + R[i2, a, b])
    return _ldl_nis(S, y)


@njit(cache=True)
def _difference_terms(P, Pd, z, zhat, R, wrap, feats, lms, feats2, lms2):
    d = z.shape[1]
    out = np.empty(feats.shape[0])
    S, y = np.empty((d, d)), np.empty(d)
    for t in range(feats.shape[0]):
        out[t] = difference_nis_kernel(P, Pd, z, zhat, R, wrap, feats[t], lms[t], feats2[t], lms2[t], S, y)
    return out


def difference_nis(problem: Problem, pairs: np.ndarray, others: np.ndarray) -> np.ndarray:
    """NIS of the difference of two pairings' innovations (the binary constraint). ``pairs`` and
    ``others`` are (q, 2) rows of (feature, landmark); row t compares (i, j) with (i', j')::

        Δ = wrap(y_ij - y_i'j') = wrap((z_i - z_i') - (zhat_j - zhat_j')),
        S_Δ = P_jj + P_j'j' - P_jj' - P_j'j + R_i + R_i' = L D Lᵀ,   NIS_Δ = Σ_a (L⁻¹ Δ)_a² / D_a

    ``Δ`` is the measured minus predicted displacement between the landmarks: an error moving both
    predictions alike (a heading error in bearings) cancels from ``Δ`` and, through ``P_jj'``, from
    ``S_Δ``; what a pose error does differently to the two stays and ``S_Δ`` weighs it. If both
    pairings are right ``NIS_Δ`` is χ²_d (to first order). Returns (q,); inf where ``S_Δ`` is
    singular.
    """
    a = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    b = np.asarray(others, dtype=np.int64).reshape(-1, 2)
    if a.shape != b.shape:
        raise ValueError(f"pairs {a.shape} and others {b.shape} must have the same shape")
    if not len(a):
        return np.zeros(0)
    return _difference_terms(problem.validate().P, np.ascontiguousarray(marginal_blocks(problem)), problem.z, problem.zhat,
                             problem.R, wrap_mask(problem), a[:, 0], a[:, 1], b[:, 0], b[:, 1])


@njit(cache=True)
def _individual_terms(P, z, zhat, R, wrap, lms, feats):
    """NIS and log det (q,) of each one-pairing hypothesis (feats[q], lms[q])."""
    d = z.shape[1]
    q = lms.shape[0]
    nis = np.empty(q)
    logdet = np.empty(q)
    C = np.zeros((zhat.shape[0], d))           # the empty hypothesis: zero moments
    G = np.zeros((zhat.shape[0], d, d))
    S, y, L, w2 = np.empty((d, d)), np.empty(d), np.empty((d, d)), np.empty(d)
    for t in range(q):
        nis[t], logdet[t] = whitened_pair(P, z, zhat, R, wrap, feats[t], lms[t], C, G, S, y, L, w2)
    return nis, logdet


@njit(cache=True)
def empty_factor(n, d):
    """The empty hypothesis' factor over ``n`` landmarks of dimension ``d`` and ``whitened_pair``'s
    work arrays: ``(Mt, w, C, G, S, y, L, w2)``."""
    return (np.zeros((n * d, n * d)), np.zeros(n * d), np.zeros((n, d)), np.zeros((n, d, d)),
            np.empty((d, d)), np.empty(d), np.empty((d, d)), np.empty(d))


@njit(cache=True)
def append_rows(Mt, w, kd, P, j, L, w2, cols):
    """Append a pairing with landmark ``j`` (``whitened_pair`` gave ``L``, ``w2``):
    ``M[kd:kd+d, l] = L⁻¹ (P[j, l] - Xᵀ M[:kd, l])`` for ``l`` in ``cols``, ``w[kd:kd+d] = w2``."""
    d = L.shape[0]
    if d == 2:
        _append_rows_2(Mt, kd, P, j, L, cols)
    else:
        _append_rows_any(Mt, kd, P, j, L, cols)
    for a in range(d):
        w[kd + a] = w2[a]


@njit(cache=True)
def _append_rows_any(Mt, kd, P, j, L, cols):
    """``append_rows``' new rows ``M[kd:kd+d, l]`` for any d: forward substitution per column."""
    d = L.shape[0]
    X = np.empty((d, d))
    for l in cols:
        _cross_block(Mt, j, l, kd, d, X)
        for b in range(d):
            col = l * d + b
            for a in range(d):
                acc = P[j * d + a, col] - X[a, b]
                for c in range(a):
                    acc -= L[a, c] * Mt[col, kd + c]
                Mt[col, kd + a] = acc / L[a, a]


@njit(cache=True)
def _append_rows_2(Mt, kd, P, j, L, cols):
    """``_append_rows_any`` for d = 2 in scalars, bit for bit."""
    l00, l10, l11 = L[0, 0], L[1, 0], L[1, 1]
    for l in cols:
        x00, x01, x10, x11 = _cross_block_2(Mt, j, l, kd)
        col = 2 * l
        m0 = (P[2 * j, col] - x00) / l00
        Mt[col, kd], Mt[col, kd + 1] = m0, ((P[2 * j + 1, col] - x10) - l10 * m0) / l11
        m0 = (P[2 * j, col + 1] - x01) / l00
        Mt[col + 1, kd], Mt[col + 1, kd + 1] = m0, ((P[2 * j + 1, col + 1] - x11) - l10 * m0) / l11


@njit(cache=True)
def advance_moments(Mt, kd, w2, cols, C, G, C_out, G_out):
    """After ``append_rows``: ``c_l + M_newᵀ w2``, ``G_l + M_newᵀ M_new`` into ``C_out[l]``,
    ``G_out[l]`` for ``l`` in ``cols``."""
    if w2.shape[0] == 2:
        _advance_moments_2(Mt, kd, w2, cols, C, G, C_out, G_out)
    else:
        _advance_moments_any(Mt, kd, w2, cols, C, G, C_out, G_out)


@njit(cache=True)
def _advance_moments_any(Mt, kd, w2, cols, C, G, C_out, G_out):
    """``advance_moments`` for any d."""
    d = w2.shape[0]
    for l in cols:
        for a in range(d):
            acc = C[l, a]
            for r in range(d):
                acc += Mt[l * d + a, kd + r] * w2[r]
            C_out[l, a] = acc
            for b in range(d):
                g = G[l, a, b]
                for r in range(d):
                    g += Mt[l * d + a, kd + r] * Mt[l * d + b, kd + r]
                G_out[l, a, b] = g


@njit(cache=True)
def _advance_moments_2(Mt, kd, w2, cols, C, G, C_out, G_out):
    """``_advance_moments_any`` for d = 2 in scalars, bit for bit."""
    w0, w1 = w2[0], w2[1]
    for l in cols:
        a0, a1, b0, b1 = Mt[2 * l, kd], Mt[2 * l, kd + 1], Mt[2 * l + 1, kd], Mt[2 * l + 1, kd + 1]
        C_out[l, 0], C_out[l, 1] = (C[l, 0] + a0 * w0) + a1 * w1, (C[l, 1] + b0 * w0) + b1 * w1
        g00, g01 = (G[l, 0, 0] + a0 * a0) + a1 * a1, (G[l, 0, 1] + a0 * b0) + a1 * b1
        g10, g11 = (G[l, 1, 0] + b0 * a0) + b1 * a1, (G[l, 1, 1] + b0 * b0) + b1 * b1
        G_out[l, 0, 0], G_out[l, 0, 1], G_out[l, 1, 0], G_out[l, 1, 1] = g00, g01, g10, g11


@njit(cache=True)
def append_pair(Mt, w, kd, P, z, zhat, R, wrap, i, j):
    """Append pairing (i, j) to the factor, every column kept. Returns (ΔNIS, Δlog det)."""
    d = z.shape[1]
    n = zhat.shape[0]
    C = np.zeros((n, d))
    G = np.zeros((n, d, d))
    L = np.empty((d, d))
    w2 = np.empty(d)
    conditional_moments(Mt, w, kd, j, C[j], G[j])
    dnis, dlogdet = whitened_pair(P, z, zhat, R, wrap, i, j, C, G, np.empty((d, d)), np.empty(d), L, w2)
    append_rows(Mt, w, kd, P, j, L, w2, np.arange(n))
    return dnis, dlogdet


def wrap_mask(problem: Problem) -> np.ndarray:
    """Boolean (d,) mask of the angular dims, read-only, cached per (d, angular)."""
    return _wrap_mask(problem.d, problem.angular)


@lru_cache(maxsize=256)
def _wrap_mask(d: int, angular: tuple[int, ...]) -> np.ndarray:
    mask = np.zeros(d, np.bool_)
    mask[list(angular)] = True
    mask.flags.writeable = False
    return mask


class JointFactor:
    """Incrementally grown Cholesky factor of a hypothesis' joint innovation covariance (the
    scorer's ``joint_terms``). With ``S_A = L Lᵀ`` and ``L w = y_A`` it keeps ``M = L⁻¹ P[J, :]``
    (as ``Mt``); pairing landmark ``j`` with feature ``i`` appends

        X = M[:, j],   L22 L22ᵀ = P_jj + R_i - XᵀX,   w2 = L22⁻¹ (y_ij - Xᵀ w),
        M_new = L22⁻¹ (P[j, :] - Xᵀ M),

    so ``NIS`` grows by ``|w2|²`` and ``log det S`` by ``2 Σ log diag L22``, O(kd·nd·d) a push.
    """

    def __init__(self, problem: Problem) -> None:
        self.problem = problem.validate()      # reads P's cross terms: the whole P is checked first
        d, n = problem.d, problem.n
        self.d = d
        self.Mt = np.zeros((n * d, n * d))
        self.w = np.zeros(n * d)
        self.k = 0
        self.nis = 0.0
        self.logdet = 0.0
        self._wrap = wrap_mask(problem)

    def push(self, i: int, j: int) -> None:
        """Append pairing (feature ``i``, landmark ``j``)."""
        p = self.problem
        dnis, dlogdet = append_pair(self.Mt, self.w, self.k * self.d, p.P, p.z, p.zhat, p.R, self._wrap, int(i), int(j))
        self.k += 1
        self.nis += dnis
        self.logdet += dlogdet
