"""Appearance: descriptors matched with Lowe's ratio test inside the Mahalanobis gate, greedy
one-to-one: the baseline showing what appearance adds to geometry where a track gives
descriptors (the photos track's SIFT). Geometry only gates; within the gate the descriptors
choose.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..association.compatibility import gated_pairs
from ..association.problem import Problem
from ..validation import in_range
from .base import CONFIDENCE, Associator, greedy_pairs


@dataclass
class Appearance(Associator):
    """For each candidate ``j``: the measurement inside its gate (NIS ``<= χ²_d(confidence)``) with
    the nearest descriptor (distance ``d₁``), and the nearest descriptor among the image's other
    measurements at another position (``d₂``; one position's several orientations count once). Kept
    when ``d₁ <= ratio · d₂`` (Lowe 2004: distinctly better than anything else in the image); kept
    pairs go greedily, smallest ``d₁`` first. A problem without descriptors is a ``ValueError``.

    confidence: gate ``χ²_d(confidence)`` on the individual NIS.
    ratio: Lowe's ratio; his 0.8 rejected 90 % of false matches and 5 % of right ones.
    """

    name = "appearance"
    summary = "descriptors: Lowe's ratio test inside the Mahalanobis gate, greedy one-to-one"
    needs_descriptors: ClassVar[bool] = True
    confidence: float = field(default=0.99, metadata=CONFIDENCE)
    ratio: float = field(default=0.8, metadata=in_range(0, 1, lo_open=True))

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.descriptors is None:
            raise ValueError("appearance needs Problem.descriptors and landmark_descriptors (the photos track "
                             "gives SIFT's); this problem has none")
        out = self.empty(problem)
        if problem.m == 0 or problem.n == 0:
            return out
        feats, lms, _, _ = gated_pairs(problem, self.confidence)
        if not len(feats):
            return out
        dist = descriptor_distances(problem.landmark_descriptors, problem.descriptors)
        gated = np.full(dist.shape, np.inf)
        gated[lms, feats] = dist[lms, feats]
        best = np.argmin(gated, axis=1)                          # (n,) nearest inside each gate
        d1 = gated[np.arange(problem.n), best]
        spot = np.unique(problem.z, axis=0, return_inverse=True)[1].ravel()
        d2 = np.where(spot[None, :] != spot[best][:, None], dist, np.inf).min(axis=1, initial=np.inf)
        keep = np.flatnonzero(np.isfinite(d1) & (d1 <= self.ratio * d2))
        return greedy_pairs(best[keep], keep, d1[keep], problem.m, problem.n)


    def warm_up(self, problem: Problem) -> None:
        """``associate`` on ``problem`` given descriptors if it has none, so the gate's kernels load
        before timing."""
        if problem.descriptors is None:
            problem = Problem(problem.z, problem.R, problem.zhat, problem.P, problem.landmark_ids, problem.volume,
                              problem.angular, descriptors=np.eye(problem.m), landmark_descriptors=np.eye(problem.n, problem.m))
        self.associate(problem)


def descriptor_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances (k, l) between the rows of ``a`` and ``b``: ``sqrt(‖a‖² + ‖b‖² − 2 a·b)``
    in float64 (exact squares for integer descriptors)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    sq = np.einsum("ij,ij->i", a, a)[:, None] + np.einsum("ij,ij->i", b, b)[None, :] - 2.0 * (a @ b.T)
    return np.sqrt(np.maximum(sq, 0.0))
