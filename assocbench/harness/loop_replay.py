"""Replay a recorded closed-loop run in this process, for pictures.

The method ran elsewhere (``execute``: a worker, a time limit, validated answers) and its
per-frame associations were recorded. Feeding them back through ``ClosedLoop.frame`` rebuilds,
frame by frame, the problem the method was given and the filter after the frame's update, without
calling the method again. A failed frame (any recorded error) is replayed as a failure, as the
worker's own resume does (``sandbox``): the filter only predicts through it. The filter is
deterministic, so the replayed estimate is the recorded one (``est_x`` … in the record).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from collections.abc import Sequence as Seq
from dataclasses import dataclass

import numpy as np

from ..association.problem import Problem
from ..tracks.camera.sequence import Sequence
from .config import RunSpec
from .loop import ClosedLoop, EstimatorFailed, recorded_answer


@dataclass(frozen=True)
class LoopFrame:
    """One replayed frame: the ``problem`` the method saw, its recorded ``association`` (n,) and
    ``error`` ("" when it succeeded), the replayed ``record`` (``ClosedLoop.frame``'s columns) and
    the filter after the frame: pose ``R`` (3, 3) camera-to-world and ``p`` (3,), the map's
    ``landmarks`` (N, 3), their marginal covariances ``landmark_covs`` (N, 3, 3) and ``confirmed`` (N,)."""

    k: int
    problem: Problem
    association: np.ndarray
    error: str
    record: dict
    R: np.ndarray
    p: np.ndarray
    landmarks: np.ndarray
    landmark_covs: np.ndarray
    confirmed: np.ndarray


def landmark_blocks(P: np.ndarray, n: int) -> np.ndarray:
    """The (n, 3, 3) diagonal blocks of the landmarks in a state ``[pose (6), l₁ (3), …, lₙ (3)]``."""
    if n == 0:
        return np.zeros((0, 3, 3))
    L = P[6:6 + 3 * n, 6:6 + 3 * n].reshape(n, 3, n, 3)
    idx = np.arange(n)
    return L[idx, :, idx, :].copy()


def replay_loop(spec: RunSpec, seq: Sequence, recorded: Mapping[int, tuple[Seq[int], str]]) -> Iterator[LoopFrame]:
    """Frames 0, 1, … of ``spec``'s closed loop on ``seq`` with the recorded ``recorded[k] =
    (association, error)``; a frame missing from ``recorded`` is replayed as failed. The frames
    end where the estimator fails (``EstimatorFailed``), as the run's poses did."""
    try:
        loop = ClosedLoop(seq, spec.belief, spec.estimator, spec.seed)
    except EstimatorFailed:   # the run's estimator failed at its start: nothing to draw
        return
    for k in range(len(seq)):
        try:
            problem, _ = loop.begin(k)
            answer = recorded_answer(recorded, k)
            record = loop.finish(*answer)
        except EstimatorFailed:   # where the run's estimator failed too: its later frames have no pose
            return
        association = recorded.get(k, (None, ""))[0]   # drawn even when the frame failed after it
        shown = np.full(problem.n, -1, np.int64) if association is None else np.asarray(association, np.int64)
        f, means = loop.filter, loop.filter.landmarks
        yield LoopFrame(k, problem, shown, answer[3], record,
                        f.R.copy(), f.p.copy(), means, landmark_blocks(f.covariance, len(means)), f.book.confirmed)
