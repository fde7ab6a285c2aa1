"""Is a log's odometry covariance right? Dead reckoning over a window of ``w`` poses from pose i
composes the increments (``sequence.composed_motion``: mean ``Δ``, covariance ``Σ_w`` as the EKF
predicts) and the reference gives ``Δ_ref``; with ``e = Δ_ref − Δ`` (θ wrapped),
``NEES = eᵀ Σ_w⁻¹ e`` has mean 3 for a right covariance. Scaling the covariance by s divides the
NEES by s, so ``mean NEES(w) / 3`` makes windows of w poses consistent (the reference's own error is
small next to a window's drift).
"""

from __future__ import annotations

import numpy as np

from ...models.range_bearing import wrap
from ...models.se2 import between
from ...sources.range_bearing_log import RangeBearingLog
from .sequence import composed_motion

POSE_DOF = 3


def window_nees(log: RangeBearingLog, poses: np.ndarray, window: int, stride: int | None = None) -> np.ndarray:
    """NEES of the dead-reckoned ``window``-pose increments against the reference ``poses``, windows
    every ``stride`` poses (default half a window)."""
    stride = stride or max(1, window // 2)
    out = []
    for i in range(0, len(poses) - window, stride):
        delta, cov = composed_motion(log.increments[i:i + window], log.increment_covariances[i:i + window])
        e = between(poses[i], poses[i + window]) - delta
        e[2] = wrap(e[2])
        out.append(float(e @ np.linalg.solve(cov, e)))
    return np.array(out)


def consistent_scale(log: RangeBearingLog, poses: np.ndarray, window: int) -> float:
    """The covariance factor that makes the mean NEES over ``window``-pose windows equal the pose's
    3 degrees of freedom."""
    return float(np.mean(window_nees(log, poses, window)) / POSE_DOF)
