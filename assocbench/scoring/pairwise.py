"""Pairwise "same landmark" scores of a whole run (the pair-counting scores of clustering). Over the
sightings ``i``, with ``e_i`` the landmark the method put each on (−1: none) and ``r_i`` the labels'
(−1: none):

    pair_precision = |{i < i′: e_i = e_i′ ≥ 0 and r_i = r_i′ ≥ 0}| / |{i < i′: e_i = e_i′ ≥ 0}|
    pair_recall    = |{i < i′: e_i = e_i′ ≥ 0 and r_i = r_i′ ≥ 0}| / |{i < i′: r_i = r_i′ ≥ 0}|

They see decisions across frames: a duplicate landmark lowers recall, a wrong merge precision.
Nothing to count: NaN.
"""

from __future__ import annotations

import numpy as np


def _pairs(keys: np.ndarray) -> int:
    """Σ over the distinct rows of ``keys`` of C(count, 2)."""
    if not len(keys):
        return 0
    counts = np.unique(keys, axis=0, return_counts=True)[1].astype(np.int64)
    return int(np.sum(counts * (counts - 1) // 2))


def same_landmark_scores(entries: np.ndarray, labels: np.ndarray) -> dict[str, float]:
    """``{"pair_precision", "pair_recall"}`` of sightings put on ``entries`` (S,) and labelled ``labels``
    (S,) (module docstring)."""
    e, r = np.asarray(entries, np.int64).reshape(-1), np.asarray(labels, np.int64).reshape(-1)
    both = _pairs(np.column_stack([e, r])[(e >= 0) & (r >= 0)])
    said, true = _pairs(e[e >= 0, None]), _pairs(r[r >= 0, None])
    return {"pair_precision": both / said if said else float("nan"),
            "pair_recall": both / true if true else float("nan")}
