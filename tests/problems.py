"""Random problems and independent reference evaluations (explicit np.linalg formulas)."""

from __future__ import annotations

import numpy as np

from assocbench import Problem


def random_spd(rng, dim: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(dim, dim))
    return scale * (A @ A.T / dim + 0.3 * np.eye(dim))


def random_problem(rng, n: int, m: int, d: int = 2, angular=()) -> Problem:
    """Correlated P, per-measurement R, measurements near predictions plus clutter."""
    P = random_spd(rng, n * d, 4.0)
    zhat = rng.uniform(0, 30, (n, d))
    z = np.vstack([zhat[rng.permutation(n)[: min(m, n)]] + rng.normal(0, 2, (min(m, n), d)),
                   rng.uniform(0, 30, (max(m - n, 0), d))])[:m]
    R = np.stack([random_spd(rng, d, 0.5) for _ in range(m)]) if m else np.zeros((0, d, d))
    return Problem(z, R, zhat, P, volume=900.0, angular=angular)


def for_method(method: str, problem: Problem, truth=None, seed: int = 0) -> Problem:
    """``problem`` as ``method`` needs it: itself for a geometric method; for a method that needs
    descriptors (its class's ``needs_descriptors``), with distinct random ones (D = 16) for the
    measurements and, for each candidate, its true measurement's (``truth`` (n,), -1: none) or a
    random one."""
    from assocbench.associators.registry import associator_class

    if not getattr(associator_class(method), "needs_descriptors", False):
        return problem
    rng = np.random.default_rng(seed)
    features = rng.integers(0, 256, (problem.m, 16)).astype(np.uint8)
    landmarks = rng.integers(0, 256, (problem.n, 16)).astype(np.uint8)
    if truth is not None:
        truth = np.asarray(truth)
        landmarks[truth >= 0] = features[truth[truth >= 0]]
    return Problem(problem.z, problem.R, problem.zhat, problem.P, problem.landmark_ids, problem.volume,
                   problem.angular, descriptors=features, landmark_descriptors=landmarks)


def wrap(y: np.ndarray, angular) -> np.ndarray:
    y = np.array(y, float)
    for a in angular:
        y[..., a] = np.arctan2(np.sin(y[..., a]), np.cos(y[..., a]))
    return y


def reference_joint(problem: Problem, association: np.ndarray) -> tuple[float, float]:
    """(NIS, log N) with an explicit inverse and determinant: the textbook formula."""
    d = problem.d
    J = np.flatnonzero(association >= 0)
    if not len(J):
        return 0.0, 0.0
    I = association[J]
    idx = np.concatenate([np.arange(j * d, (j + 1) * d) for j in J])
    S = problem.P[np.ix_(idx, idx)].copy()
    for a, i in enumerate(I):
        S[a * d:(a + 1) * d, a * d:(a + 1) * d] += problem.R[i]
    y = wrap(problem.z[I] - problem.zhat[J], problem.angular).ravel()
    nis = float(y @ np.linalg.inv(S) @ y)
    loglik = float(-0.5 * nis - 0.5 * np.linalg.slogdet(2 * np.pi * S)[1])
    return nis, loglik


def reference_surprisal(problem: Problem, association: np.ndarray) -> float:
    n_unassociated = int(np.sum(association < 0))
    return n_unassociated * np.log(problem.volume) - reference_joint(problem, association)[1]


def exhaustive_best(problem: Problem, confidence: float) -> tuple[int, float, np.ndarray]:
    """Most pairings, then lowest NIS, over every individually compatible one-to-one
    hypothesis that is jointly compatible: (count, NIS, association)."""
    from scipy.stats import chi2

    d, n, m = problem.d, problem.n, problem.m
    ic = np.zeros((m, n), bool)
    for i in range(m):
        for j in range(n):
            a = np.full(n, -1)
            a[j] = i
            ic[i, j] = reference_joint(problem, a)[0] <= chi2.ppf(confidence, d)
    best = (0, 0.0, np.full(n, -1))
    assoc = np.full(n, -1)

    def visit(j: int, used: set) -> None:
        nonlocal best
        if j == n:
            k = int(np.sum(assoc >= 0))
            if k == 0:
                return
            nis = reference_joint(problem, assoc)[0]
            if nis <= chi2.ppf(confidence, d * k) and (k > best[0] or (k == best[0] and nis < best[1])):
                best = (k, nis, assoc.copy())
            return
        visit(j + 1, used)
        for i in np.flatnonzero(ic[:, j]):
            if i not in used:
                assoc[j] = i
                visit(j + 1, used | {int(i)})
                assoc[j] = -1

    visit(0, set())
    return best
