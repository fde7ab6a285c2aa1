"""A textbook JCBB kept as the speed baseline: the same criterion as ours (the largest jointly
compatible hypothesis, ties by lowest joint NIS), computed the plain way.

* landmarks in index order, every feature tried for every landmark (no pre-filter: landmarks
  and features without a compatible partner stay in the search);
* the joint innovation covariance ``P[J,J] + blockdiag(R)`` is rebuilt and refactorised
  (Cholesky) at every node;
* the bound is ``k + remaining landmarks``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.stats import chi2

from assocbench.association.compatibility import wrap_angles


def joint_nis(problem, pairs: list[tuple[int, int]]) -> float:
    d = problem.d
    J = np.array([j for _, j in pairs])
    I = np.array([i for i, _ in pairs])
    rows = (J[:, None] * d + np.arange(d)).ravel()
    S = problem.P[np.ix_(rows, rows)].copy()
    for a, i in enumerate(I):
        S[a * d:(a + 1) * d, a * d:(a + 1) * d] += problem.R[i]
    y = wrap_angles(problem.z[I] - problem.zhat[J], problem.angular).ravel()
    return float(y @ cho_solve(cho_factor(S, lower=True), y))


def textbook_jcbb(problem, confidence: float = 0.99) -> np.ndarray:
    n, m, d = problem.n, problem.m, problem.d
    gate = [chi2.ppf(confidence, d * k) if k else 0.0 for k in range(n + 1)]
    best = {"k": 0, "nis": 0.0, "pairs": []}

    def visit(j: int, pairs: list, used: set, nis: float) -> None:
        k = len(pairs)
        if nis <= gate[k] and (k > best["k"] or (k == best["k"] and nis < best["nis"])):
            best.update(k=k, nis=nis, pairs=list(pairs))
        remaining = n - j
        if j == n or k + remaining < best["k"] or (k + remaining == best["k"] and nis >= best["nis"]):
            return
        for i in range(m):
            if i in used or joint_nis(problem, [(i, j)]) > gate[1]:      # individual gate
                continue
            child = joint_nis(problem, pairs + [(i, j)])                  # full refactorisation
            if child <= gate[k + remaining]:
                visit(j + 1, pairs + [(i, j)], used | {i}, child)
        visit(j + 1, pairs, used, nis)

    visit(0, [], set(), 0.0)
    out = np.full(n, -1, dtype=np.int64)
    for i, j in best["pairs"]:
        out[j] = i
    return out
