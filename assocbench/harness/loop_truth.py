"""Truth of the closed loop: which map entry is which true landmark, and what a map is worth. The
estimator never sees it. Each map entry is tied when made to the landmark its feature truly imaged,
or to none (-1: a look-alike texture corner or clutter); pairing with an entry tied to none is
false, and such an entry is a false landmark (a texture corner is no fixed point: it slides with the
view).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.problem import NO_MATCH
from ..association.truth import FrameTruth


@dataclass
class MapTruth:
    """The landmark each map id truly is (``label``: landmark index, or -1 for none)."""

    label: dict[int, int] = field(default_factory=dict)

    def tie(self, map_id: int, label: int) -> None:
        self.label[map_id] = int(label)


def loop_truth(map_ids: np.ndarray, truth: MapTruth, labels: np.ndarray, visible: np.ndarray) -> FrameTruth:
    """Truth of a closed-loop problem: each candidate's truly imaging feature, one-to-one, older
    entries first (a later duplicate pairs with nothing); ``labels`` (m,), ``visible`` (n,)."""
    association = np.full(len(map_ids), NO_MATCH, dtype=np.int64)
    feature_labels = np.full(len(labels), NO_MATCH, dtype=np.int64)
    features_of: dict[int, list[int]] = {}
    for i, lm in enumerate(labels):
        if lm >= 0:
            features_of.setdefault(int(lm), []).append(i)
    for c in np.argsort(map_ids, kind="stable"):
        label = truth.label[int(map_ids[c])]
        if label >= 0 and label in features_of:
            features = features_of.pop(label)
            association[c] = features[-1]
            # every feature of the landmark names the entry: two pieces of one wall both pair right
            feature_labels[features] = map_ids[c]
    return FrameTruth(feature_labels, association, visible)


def map_quality(map_ids: list[int], confirmed: np.ndarray, estimates: np.ndarray, truth: MapTruth,
                landmarks: np.ndarray) -> dict[str, float]:
    """Confirmed ``map_size``, ``duplicates``, ``false_landmarks`` (tied to none) and ``map_rmse``
    (m) of the tied ones."""
    labels = np.array([truth.label[m] for m in map_ids], dtype=np.int64)[np.asarray(confirmed, bool)]
    tied = labels >= 0
    errors = np.linalg.norm(np.asarray(estimates)[np.asarray(confirmed, bool)][tied] - landmarks[labels[tied]], axis=1)
    return {"map_size": int(len(labels)), "duplicates": int(tied.sum() - len(np.unique(labels[tied]))),
            "false_landmarks": int((~tied).sum()),
            "map_rmse": float(np.sqrt(np.mean(errors ** 2))) if len(errors) else float("nan")}


REVISIT_GAP = 50   # frames without a measurement of a landmark after which measuring it again is a revisit


@dataclass
class RevisitCounter:
    """Loop closures from the truth (the same opportunities for every method): a landmark measured
    in frame k whose previous true measurement was at least ``REVISIT_GAP`` frames before is a
    *revisit*; the method *closes the loop* when it pairs it with an entry of that landmark made no
    later than that previous measurement (one made during the revisit is a duplicate)."""

    last: dict[int, int] = field(default_factory=dict)   # landmark -> frame of its last true measurement

    def count(self, k: int, labels: np.ndarray, map_ids: np.ndarray, association: np.ndarray | None,
              truth: MapTruth, born: dict[int, int]) -> dict[str, int]:
        """``{"revisits", "loop_closures"}`` of frame ``k`` (``association`` None for a failed
        frame); then remember the frame."""
        paired = {} if association is None else {int(i): int(map_ids[j]) for j, i in enumerate(association) if i >= 0}
        revisits = closures = 0
        for i, lm in enumerate(labels):
            lm = int(lm)
            if lm < 0:
                continue
            previous = self.last.get(lm)
            if previous is not None and k - previous >= REVISIT_GAP:
                revisits += 1
                m = paired.get(i)
                closures += int(m is not None and truth.label.get(m) == lm and born.get(m, k) <= previous)
            self.last[lm] = k
        return {"revisits": revisits, "loop_closures": closures}
