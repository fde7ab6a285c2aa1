"""Scores of the dense track: correspondences against per-pixel truth, relative pose errors.

A source point (a map point, or a pixel of an earlier frame) carries the true surface point it
stands for and the geom it lies on; so does every pixel of a frame (``DepthFrame.true_points``,
``geom``). A pair (source point i, pixel j) is **true** when both lie on the same geom and their
true positions are within ``tol`` of each other. A source point **has a partner** in a frame when
its true position, projected with the frame's true pose, lands on a measured pixel that would make
a true pair with it (so a point hidden behind another surface, or outside the view, has none).

    precision = true pairs / pairs,    recall = source points truly paired / source points with a partner

Both are NaN when their denominator is 0, never 0 or 1 by default.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...models.depth_frame import DepthFrame
from ...scoring.trajectory import rotation_errors_deg


@dataclass(frozen=True)
class CorrespondenceScore:
    pairs: int
    true_pairs: int
    partners: int        # source points with a true partner in the frame
    precision: float
    recall: float


def true_pairs(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame, source: np.ndarray,
               pixel: np.ndarray, tol: float) -> np.ndarray:
    """Mask of the pairs (``source[i]``, flat ``pixel[i]``) that are true: same geom, true positions
    within ``tol``."""
    q = frame.true_points.reshape(-1, 3)[pixel]
    same = frame.geom.reshape(-1)[pixel] == src_geom[source]
    close = np.linalg.norm(q - src_true[source], axis=1) < tol
    return same & close


def has_partner(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame, tol: float) -> np.ndarray:
    """Mask of source points whose true position, seen from the frame's true pose, lands on a
    measured pixel of the same geom within ``tol`` (the nearest pixel to its projection)."""
    K = frame.K
    rc = (src_true - frame.t) @ frame.R
    z = rc[:, 2]
    ok = np.isfinite(z) & (z > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.rint(K.f * rc[:, 0] / z + K.cx)
        v = np.rint(K.f * rc[:, 1] / z + K.cy)
    ok &= (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    idx = np.flatnonzero(ok)
    pix = v[idx].astype(np.int64) * K.width + u[idx].astype(np.int64)
    measured = frame.valid.reshape(-1)[pix]
    partner = np.zeros(len(src_true), bool)
    partner[idx] = measured & true_pairs(src_true, src_geom, frame, idx, pix, tol)
    return partner


def score_correspondences(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame, source: np.ndarray,
                          pixel: np.ndarray, tol: float) -> CorrespondenceScore:
    """Precision and recall of the pairs (``source``, ``pixel``) against the frame's truth."""
    return score_associations(src_true, src_geom, frame, [(source, pixel)], tol)[0]


def score_associations(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame,
                       associations: Sequence[tuple[np.ndarray, np.ndarray]], tol: float) -> list[CorrespondenceScore]:
    """``score_correspondences`` of several associations (source, pixel) of one source set with one
    frame (ICP's first and last): the partners (``has_partner``) depend on those two only, so they
    are found once."""
    partner = has_partner(src_true, src_geom, frame, tol)
    n_partner = int(partner.sum())
    scores = []
    for source, pixel in associations:
        right = true_pairs(src_true, src_geom, frame, source, pixel, tol)
        found = np.zeros(len(src_true), bool)
        found[source[right]] = True
        precision = float(right.sum() / len(source)) if len(source) else float("nan")
        recall = float((found & partner).sum() / n_partner) if n_partner else float("nan")
        scores.append(CorrespondenceScore(len(source), int(right.sum()), n_partner, precision, recall))
    return scores


def relative_pose_error(R0_true: np.ndarray, t0_true: np.ndarray, R1_true: np.ndarray, t1_true: np.ndarray,
                        R0_est: np.ndarray, t0_est: np.ndarray, R1_est: np.ndarray,
                        t1_est: np.ndarray) -> tuple[float, float]:
    """Translation (m) and rotation (deg) of ``Δ_true⁻¹ Δ_est`` where ``Δ = T0⁻¹ T1`` is the motion
    from frame 0 to frame 1 (the RPE of one step; 0 for a perfect step whatever the drift before)."""
    dR_true, dt_true = R0_true.T @ R1_true, R0_true.T @ (t1_true - t0_true)
    dR_est, dt_est = R0_est.T @ R1_est, R0_est.T @ (t1_est - t0_est)
    trans = float(np.linalg.norm(dR_true.T @ (dt_est - dt_true)))
    return trans, float(rotation_errors_deg(dR_true[None], dR_est[None])[0])
