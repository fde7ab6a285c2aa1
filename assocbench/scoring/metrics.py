"""Per-frame scores of an association against the truth.

With ``a`` the returned and ``t`` the true association (feature index per candidate or -1):

* TP: ``a_j >= 0`` and ``a_j = t_j``;   FP: ``a_j >= 0`` and ``a_j != t_j``;
  FN: ``t_j >= 0`` and ``a_j != t_j``.
* clutter_accepted: FPs whose feature images no mapped landmark (a distractor or clutter).
* missed_true: candidates with a true feature that were left unassociated.
* surprisal / surprisal_true: ``s(a)`` and ``s(t)``; their difference says whether the
  method found something the model finds more (or less) likely than the truth.
* jointly_compatible: whether ``a`` passes the joint χ² test at the method-independent
  confidence ``JC_CONFIDENCE``.
"""

from __future__ import annotations

import numpy as np

from ..association.compatibility import joint_verdict, surprisal
from ..association.problem import NO_MATCH, Problem
from ..belief.camera_belief import FrameTruth

JC_CONFIDENCE = 0.99


def score_frame(problem: Problem, truth: FrameTruth, association: np.ndarray) -> dict[str, float]:
    """Counts and surprisal of one frame (see module docstring)."""
    a, t = association, truth.association
    paired = a >= 0
    tp = int(np.sum(paired & (a == t)))
    fp = int(np.sum(paired & (a != t)))
    fn = int(np.sum((t >= 0) & (a != t)))
    clutter = int(np.sum(paired & (a != t) & (truth.feature_labels[np.maximum(a, 0)] == NO_MATCH)))
    s, compatible = joint_verdict(problem, a, JC_CONFIDENCE)
    return {
        "n": problem.n, "m": problem.m, "n_true": int(np.sum(t >= 0)),
        "tp": tp, "fp": fp, "fn": fn, "clutter_accepted": clutter,
        "missed_true": int(np.sum((t >= 0) & ~paired)),
        "perfect": bool(np.array_equal(a, t)),
        "surprisal": s, "surprisal_true": surprisal(problem, t), "jointly_compatible": compatible,
    }


def unscored_frame(problem: Problem, truth: FrameTruth) -> dict[str, float]:
    """Record of a frame the method failed on: scored as if it had returned no pairing."""
    return score_frame(problem, truth, np.full(problem.n, NO_MATCH, dtype=np.int64))
