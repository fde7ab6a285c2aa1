"""The truth of one association problem, the same for every track: which map landmark each
measurement images (or -1 for clutter and look-alikes), the true pairing of each candidate and
which candidates were really visible. Scoring compares an ``Association`` with it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FrameTruth:
    """Truth of one problem: ``feature_labels`` (m,) map id or -1; ``association`` (n,) the true
    feature of each candidate or -1; ``visible`` (n,) whether each candidate is really visible."""

    feature_labels: np.ndarray
    association: np.ndarray
    visible: np.ndarray
