"""What a method decided about each feature of a frame, in the words a picture's key uses."""

from __future__ import annotations

import numpy as np

# every decision, in the order a key lists them
DECISIONS = ("right", "also", "wrong", "missed", "new", "clutter")


def feature_decisions(landmark_ids: np.ndarray, labels: np.ndarray, association: np.ndarray,
                      real: np.ndarray) -> list[str]:
    """The decision about each feature ``i`` (m = ``len(labels)``), from the candidates' map ids
    ``landmark_ids`` (n,), the truth's ``labels`` (m,) (the map id feature ``i`` truly images, or
    −1), the method's ``association`` (n,) (``a[j]``: the feature paired with candidate j, −1: none)
    and ``real`` (m,) (the feature images a landmark of the scene, mapped or not):

    * ``right``: paired with candidate j and ``landmark_ids[j] = labels[i]``;
    * ``also``: left unpaired while another feature of the same landmark was paired right (a wall
      split by a doorway gives several lines, a post seen twice two detections: one pairing per
      landmark is all an association holds);
    * ``wrong``: paired with another landmark's candidate (a clutter feature paired is wrong too);
    * ``missed``: left unpaired though its landmark is a candidate;
    * ``new``: left unpaired, a real landmark that is not a candidate (not in the map, or not
      predicted in view): a SLAM filter makes a new landmark of it;
    * ``clutter``: left unpaired and images no landmark (a spurious detection or added clutter).
    """
    landmark_ids, labels = np.asarray(landmark_ids, np.int64), np.asarray(labels, np.int64)
    paired = {int(i): int(landmark_ids[j]) for j, i in enumerate(np.asarray(association, np.int64)) if i >= 0}
    updated = {lm for i, lm in paired.items() if lm == labels[i]}
    candidates = set(landmark_ids.tolist())
    out = []
    for i, label in enumerate(labels.tolist()):
        if i in paired:
            out.append("right" if paired[i] == label else "wrong")
        elif label >= 0 and label in updated:
            out.append("also")
        elif label >= 0 and label in candidates:
            out.append("missed")
        else:
            out.append("new" if real[i] else "clutter")
    return out
