"""Per-pair features of a ``Problem`` for the learned associator, from the compatibility module: a
row per pair inside a loose gate ``NIS_ij <= χ²_d(GATE_CONFIDENCE)``. Changing them changes
``FEATURE_VERSION``, and a model of another version is refused (its trees split on other
quantities)."""

from __future__ import annotations

import numpy as np

from ...association.compatibility import chi2_threshold, gated_pairs, log_gaussian, pair_innovations, stacked_nis
from ...association.problem import Problem

FEATURE_VERSION = 1
GATE_CONFIDENCE = 0.999   # looser than the classical methods' 0.99: the model, not the gate, decides
FEATURES = (
    "nis",               # y_ijᵀ S_ij⁻¹ y_ij
    "logdet",            # log det S_ij
    "log_odds_clutter",  # log N(y_ij; 0, S_ij) + log|Y|: the pair against a uniform clutter feature
    "landmark_rank",     # rank of the pair's NIS among the landmark's gated features (0: best)
    "landmark_gap",      # NIS_ij minus the best NIS of the landmark's other features (gate if none)
    "feature_rank",      # rank among the feature's gated landmarks
    "feature_gap",       # NIS_ij minus the best NIS of the feature's other landmarks
    "landmark_count",    # gated features of the landmark
    "feature_count",     # gated landmarks of the feature
    "common_mode_nis",   # NIS of y_ij minus the median innovation of the mutual-best pairs (a shared pose error)
    "log_features_per_candidate",   # log((m + 1) / (n + 1)): clutter and missing map
    "gated_per_candidate",          # gated pairs / n: how crowded the gate is
)


def pair_features(problem: Problem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(feats, lms, X)``: the gated pairs (feature ``feats[t]``, landmark ``lms[t]``) and their
    features ``X`` (pairs, len(FEATURES)) in ``FEATURES`` order."""
    feats, lms, nis, logdet = gated_pairs(problem, GATE_CONFIDENCE)
    k, gate = len(feats), chi2_threshold(problem.d, GATE_CONFIDENCE)
    X = np.zeros((k, len(FEATURES)))
    if k == 0:
        return feats, lms, X
    y, S = pair_innovations(problem, feats, lms)
    landmark_rank, landmark_gap, landmark_count = _group_ranks(lms, nis, gate)
    feature_rank, feature_gap, feature_count = _group_ranks(feats, nis, gate)
    mutual = (landmark_rank == 0) & (feature_rank == 0)
    shift = np.median(y[mutual], axis=0) if mutual.sum() >= 3 else np.zeros(problem.d)
    X[:, 0], X[:, 1] = nis, logdet
    X[:, 2] = log_gaussian(nis, logdet, problem.d) + np.log(problem.volume)
    X[:, 3], X[:, 4], X[:, 5], X[:, 6] = landmark_rank, landmark_gap, feature_rank, feature_gap
    X[:, 7], X[:, 8] = landmark_count, feature_count
    X[:, 9] = stacked_nis(y - shift, S)
    X[:, 10] = np.log((problem.m + 1) / (problem.n + 1))
    X[:, 11] = k / problem.n
    return feats, lms, X


def _group_ranks(group: np.ndarray, nis: np.ndarray, gate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair: the rank of its NIS within its group (ties by list order), its NIS minus the
    best NIS of the group's other pairs (``nis - gate`` when alone), and the group's size."""
    order = np.lexsort((np.arange(len(nis)), nis, group))
    g, v = group[order], nis[order]
    start = np.r_[0, np.flatnonzero(g[1:] != g[:-1]) + 1]
    sizes = np.diff(np.r_[start, len(g)])
    first = np.repeat(start, sizes)
    rank = np.arange(len(g)) - first
    second = np.where(sizes > 1, v[np.minimum(start + 1, len(g) - 1)], gate)
    best_other = np.where(rank == 0, np.repeat(second, sizes), v[first])
    out_rank, out_gap, out_size = (np.empty(len(g)) for _ in range(3))
    out_rank[order], out_gap[order], out_size[order] = rank, v - best_other, np.repeat(sizes, sizes)
    return out_rank, out_gap, out_size
