"""Per-frame scores of an association ``a`` against the truth ``t`` (feature index per candidate or
-1):

* TP: ``a_j >= 0`` and ``a_j ≡ t_j``; FP: ``a_j >= 0`` and not ``a_j ≡ t_j``; FN: ``t_j >= 0`` and
  not ``a_j ≡ t_j``. ``a_j ≡ t_j``: the same feature, or (``t_j >= 0``) two features with one truth
  label (two pieces of one wall's line); for point landmarks ``≡`` is ``=``.
* clutter_accepted: FPs whose feature images no mapped landmark; missed_true: candidates with a true
  feature left unassociated.
* surprisal / surprisal_true: ``s(a)`` and ``s(t)``: did the method find something the model finds
  more likely than the truth?
* jointly_compatible: ``a`` passes the joint χ² test at ``JC_CONFIDENCE`` (the same for every
  method).
* true_mass (soft associators): ``mean_j β_{j, t_j}``.
"""

from __future__ import annotations

import numpy as np

from ..association.compatibility import joint_verdict, surprisal
from ..association.problem import NO_MATCH, Problem
from ..association.truth import FrameTruth

JC_CONFIDENCE = 0.99


def score_frame(problem: Problem, truth: FrameTruth, association: np.ndarray) -> dict[str, float]:
    """Counts and surprisal of one frame (see module docstring)."""
    a, t = association, truth.association
    paired = a >= 0
    right = paired & same_feature(a, t, truth.feature_labels)
    tp = int(np.sum(right))
    fp = int(np.sum(paired & ~right))
    fn = int(np.sum((t >= 0) & ~right))
    wrong = paired & ~right   # a frame with no feature has no pairing to look up
    clutter = int(np.sum(truth.feature_labels[a[wrong]] == NO_MATCH)) if wrong.any() else 0
    s, compatible = joint_verdict(problem, a, JC_CONFIDENCE)
    return {
        "n": problem.n, "m": problem.m, "n_true": int(np.sum(t >= 0)),
        "tp": tp, "fp": fp, "fn": fn, "clutter_accepted": clutter,
        "missed_true": int(np.sum((t >= 0) & ~paired)),
        "perfect": bool(np.all(right | (~paired & (t < 0)))),
        "surprisal": s, "surprisal_true": surprisal(problem, t), "jointly_compatible": compatible,
    }


def same_feature(a: np.ndarray, t: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(n,) ``a_j ≡ t_j`` (module docstring): the same feature, or two features with one truth label."""
    both = (a >= 0) & (t >= 0)
    same_label = np.zeros(len(a), bool)
    if both.any():
        same_label[both] = labels[a[both]] == labels[t[both]]
    return (a == t) | same_label


def unscored_frame(problem: Problem, truth: FrameTruth) -> dict[str, float]:
    """Record of a failed frame: counts as if no pairing was returned (recall pays); ``surprisal``
    and ``jointly_compatible`` NaN, since the empty set would pass the joint test trivially."""
    counts = score_frame(problem, truth, np.full(problem.n, NO_MATCH, dtype=np.int64))
    return counts | {"surprisal": float("nan"), "jointly_compatible": float("nan")}


def true_mass(marginals: np.ndarray, truth_association: np.ndarray) -> float:
    """Mean probability mass a soft associator puts on each candidate's true outcome:

        true_mass = (1/n) Σ_j β_{j, t_j},   column t_j = m (the last, "unassociated") when t_j = -1,

    for marginals ``β`` (n, m + 1) and the truth ``t`` (n,): 1.0 for a perfect one-hot answer, 0.0
    when all mass is wrong, NaN with no candidate. ``ValueError`` for shapes that disagree or ``t``
    outside ``-1..m-1``.
    """
    beta = np.asarray(marginals, dtype=np.float64)
    t = np.asarray(truth_association)
    if beta.ndim != 2 or t.shape != (beta.shape[0],):
        raise ValueError(f"marginals of shape {beta.shape} do not fit a truth of shape {t.shape}: "
                         "expected (n, m + 1) and (n,)")
    m = beta.shape[1] - 1
    if t.size and (t.min() < NO_MATCH or t.max() >= m):
        raise ValueError(f"truth pairs a candidate with a feature outside -1..{m - 1}")
    if t.size == 0:
        return float("nan")
    cols = np.where(t == NO_MATCH, m, t).astype(np.int64)
    return float(beta[np.arange(len(t)), cols].mean())
