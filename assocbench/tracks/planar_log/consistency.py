"""Is a log's odometry covariance right? Its NEES against the reference solution over windows of
``w`` poses, and the covariance scale that makes one window length consistent.

For a window starting at pose i, dead reckoning composes the log's increments from i to i + w
(``sequence.composed_motion``: mean ``Δ``, covariance ``Σ_w`` propagated step by step as the EKF
predicts) and the reference solution gives the pose of i + w in i's frame, ``Δ_ref``. With
``e = Δ_ref − Δ`` (θ wrapped), ``NEES = eᵀ Σ_w⁻¹ e``: a covariance that describes the odometry's
error gives a mean of 3 over the windows. A covariance scaled by s divides the NEES by s, so the
scale that makes windows of w poses consistent is ``mean NEES(w) / 3``. (The reference poses carry
an error of their own, small next to a window's drift.)
"""

from __future__ import annotations

import numpy as np

from ...models.range_bearing import wrap
from ...models.se2 import between
from ...sources.range_bearing_log import RangeBearingLog
from .sequence import composed_motion

POSE_DOF = 3


def window_nees(log: RangeBearingLog, poses: np.ndarray, window: int, stride: int | None = None) -> np.ndarray:
    """NEES of the dead-reckoned ``window``-pose increments against the reference ``poses`` (N, 3),
    windows starting every ``stride`` poses (default: half a window, at least 1)."""
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
