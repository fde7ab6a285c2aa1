"""What a method decided about each feature of a frame, in the words a picture's key uses."""

from __future__ import annotations

import numpy as np

# every decision, in the order a key lists them
DECISIONS = ("right", "also", "wrong", "missed", "new", "clutter")


def feature_decisions(landmark_ids: np.ndarray, labels: np.ndarray, association: np.ndarray,
                      real: np.ndarray) -> list[str]:
    """The decision about each feature ``i``, from the candidates' map ids ``landmark_ids`` (n,),
    the truth's ``labels`` (m,) (the map id it images, −1: none), the ``association`` (n,) and
    ``real`` (m,) (it images a scene landmark, mapped or not):

    * ``right``: paired with candidate j and ``landmark_ids[j] = labels[i]``;
    * ``also``: unpaired while another feature of its landmark was paired right (one pairing per
      landmark is all an association holds);
    * ``wrong``: paired with another landmark's candidate (a clutter feature paired too);
    * ``missed``: unpaired though its landmark is a candidate;
    * ``new``: unpaired, a real landmark that is not a candidate (a SLAM filter makes it a
      landmark);
    * ``clutter``: unpaired and images no landmark.
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
