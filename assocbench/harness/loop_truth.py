"""Truth of the closed loop: which map entry is which true landmark, and what a map is worth.

The estimator never sees any of this. Each map entry is tied, when it is made, to what its
feature truly imaged: a landmark (its index) or, for a look-alike corner of the wall texture
(label -1), the 3-D point the rendered depth and the true pose put under the feature. A feature
and a map entry truly pair when they image the same landmark, or the same texture corner
(points within ``POINT_TOLERANCE_M``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.problem import NO_MATCH
from ..belief.camera_belief import FrameTruth

POINT_TOLERANCE_M = 0.03   # the rendered depth's rounding at 3 m is about 1 cm (measured)


@dataclass
class MapTruth:
    """What each map id truly is: ``label`` (landmark index, or -1 for a texture corner) and
    ``point`` (its true 3-D position)."""

    label: dict[int, int] = field(default_factory=dict)
    point: dict[int, np.ndarray] = field(default_factory=dict)

    def tie(self, map_id: int, label: int, point: np.ndarray) -> None:
        self.label[map_id], self.point[map_id] = int(label), np.asarray(point, dtype=float)


def back_project(features: np.ndarray, depth: np.ndarray, R: np.ndarray, p: np.ndarray, K) -> np.ndarray:
    """World points ``p + R z [(u − c_x)/f, (v − c_y)/f, 1]`` of pixels at z-depths (NaN rows where
    the depth is NaN)."""
    rc = np.column_stack([(features[:, 0] - K.cx) / K.f * depth, (features[:, 1] - K.cy) / K.f * depth, depth])
    return rc @ R.T + p


def same_thing(labels: np.ndarray, points: np.ndarray, map_label: int, map_point: np.ndarray) -> np.ndarray:
    """(m,) whether each feature images what a map entry is (same landmark, or same corner)."""
    if map_label >= 0:
        return labels == map_label
    near = np.linalg.norm(points - map_point, axis=1) < POINT_TOLERANCE_M
    return (labels == NO_MATCH) & np.nan_to_num(near, nan=0).astype(bool)


def loop_truth(map_ids: np.ndarray, truth: MapTruth, labels: np.ndarray, points: np.ndarray,
               visible: np.ndarray) -> FrameTruth:
    """Truth of a closed-loop problem: the true feature of each candidate, one-to-one, older map
    entries first (a duplicate made later truly pairs with nothing). ``visible`` (n,)."""
    association = np.full(len(map_ids), NO_MATCH, dtype=np.int64)
    taken = np.zeros(len(labels), bool)
    for c in np.argsort(map_ids, kind="stable"):
        mid = int(map_ids[c])
        hits = np.flatnonzero(same_thing(labels, points, truth.label[mid], truth.point[mid]) & ~taken)
        if len(hits):
            association[c] = hits[0]
            taken[hits[0]] = True
    feature_labels = np.full(len(labels), NO_MATCH, dtype=np.int64)
    feature_labels[association[association >= 0]] = map_ids[association >= 0]
    return FrameTruth(feature_labels, association, visible)


def map_quality(map_ids: list[int], confirmed: np.ndarray, estimates: np.ndarray, truth: MapTruth,
                landmarks: np.ndarray) -> dict[str, float]:
    """Confirmed map entries, ``duplicates`` (entries beyond the first for one true thing),
    ``false_landmarks`` (entries not tied to a landmark: texture corners) and ``map_rmse`` (m) of
    the entries tied to a landmark (against its true position)."""
    seen_labels: set[int] = set()
    seen_points: list[np.ndarray] = []
    dup = false = 0
    errors = []
    for mid, ok, est in zip(map_ids, confirmed, estimates):
        if not ok:
            continue
        label = truth.label[mid]
        if label >= 0:
            errors.append(np.linalg.norm(est - landmarks[label]))
            dup += label in seen_labels
            seen_labels.add(label)
            continue
        false += 1
        point = truth.point[mid]
        dup += any(np.linalg.norm(point - q) < POINT_TOLERANCE_M for q in seen_points)
        seen_points.append(point)
    rmse = float(np.sqrt(np.mean(np.square(errors)))) if errors else float("nan")
    return {"map_size": int(np.sum(confirmed)), "duplicates": dup, "false_landmarks": false, "map_rmse": rmse}
