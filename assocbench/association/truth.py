"""The truth of one association problem, the same for every track: which map landmark each
measurement images (-1: clutter, look-alikes), each candidate's true pairing, and which candidates
were really visible."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import NO_MATCH, Problem


@dataclass(frozen=True)
class FrameTruth:
    """Truth of one problem: ``feature_labels`` (m,) map id or -1; ``association`` (n,) each
    candidate's true feature or -1; ``visible`` (n,)."""

    feature_labels: np.ndarray
    association: np.ndarray
    visible: np.ndarray

    def validate(self, problem: Problem) -> FrameTruth:
        """Check the truth against ``problem``, raising ``ValueError`` naming the field; returns it.
        Shapes (m,), (n,), (n,); labels ≥ -1; ``association`` in -1..m-1, one-to-one, and agreeing
        with the labels: ``t_j = i ≥ 0 ⇒ feature_labels[i] = landmark_ids[j]``, ``t_j = -1 ⇒`` no
        feature labelled ``landmark_ids[j]``. A truth that breaks these would score every method
        against impossible pairs."""
        labels, t, visible = (np.asarray(a) for a in (self.feature_labels, self.association, self.visible))
        for name, arr, size, kind in (("feature_labels", labels, problem.m, "integer"),
                                      ("association", t, problem.n, "integer"), ("visible", visible, problem.n, "bool")):
            if arr.shape != (size,):
                raise ValueError(f"FrameTruth.{name} has shape {arr.shape}, expected ({size},)")
            if size and not np.issubdtype(arr.dtype, np.integer if kind == "integer" else np.bool_):
                raise ValueError(f"FrameTruth.{name} must be {kind}, got {arr.dtype}")
        if np.any(labels < NO_MATCH):
            raise ValueError(f"FrameTruth.feature_labels holds {labels.min()}: a label is a map id or -1")
        if np.any((t < NO_MATCH) | (t >= problem.m)):
            bad = t[(t < NO_MATCH) | (t >= problem.m)][0]
            raise ValueError(f"FrameTruth.association pairs a candidate with feature {bad}, outside -1..{problem.m - 1}")
        used = t[t >= 0]
        if len(np.unique(used)) != len(used):
            dup = int(np.flatnonzero(np.bincount(used) > 1)[0])
            raise ValueError(f"FrameTruth.association pairs feature {dup} with more than one candidate")
        _check_labels_agree(labels, t, np.asarray(problem.landmark_ids))
        return self


def _check_labels_agree(labels: np.ndarray, t: np.ndarray, ids: np.ndarray) -> None:
    """``FrameTruth.validate``'s last rule: the true pairs and the feature labels say the same."""
    paired = np.flatnonzero(t >= 0)
    wrong = paired[labels[t[paired]] != ids[paired]]
    if len(wrong):
        j = int(wrong[0])
        raise ValueError(f"FrameTruth.association pairs candidate {j} (landmark {ids[j]}) with feature {t[j]}, "
                         f"which is labelled {labels[t[j]]}")
    unpaired = np.flatnonzero((t < 0) & np.isin(ids, labels[labels >= 0]))
    if len(unpaired):
        j = int(unpaired[0])
        raise ValueError(f"FrameTruth.association leaves candidate {j} unpaired, but feature "
                         f"{int(np.flatnonzero(labels == ids[j])[0])} is labelled its landmark {ids[j]}")
