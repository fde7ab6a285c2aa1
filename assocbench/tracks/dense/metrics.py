"""Scores of the dense track: correspondences against per-pixel truth, relative pose errors.

Source points and pixels carry their true surface point and geom. A pair is **true** when both lie
on one geom within ``tol``; a source point **has a partner** when its true position, projected with
the true pose, lands on a pixel it would truly pair with.

    precision = true pairs / pairs,    recall = source points truly paired / source points with a partner

NaN when the denominator is 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

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
    within ``tol``: ``g_s = g_q`` and ``|X_s − X_q|² < tol²``."""
    tp, geom = _truth_maps(frame)
    out = np.empty(len(source), np.bool_)
    _true_pairs_kernel(_f64(src_true), np.ascontiguousarray(src_geom, dtype=np.int64), tp, geom,
                       np.ascontiguousarray(source, dtype=np.int64), np.ascontiguousarray(pixel, dtype=np.int64),
                       float(tol) ** 2, out)
    return out


def has_partner(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame, tol: float) -> np.ndarray:
    """Source points whose true position, projected with the true pose to its nearest pixel, lands
    on a pixel of the same geom within ``tol``."""
    K = frame.K
    tp, geom = _truth_maps(frame)
    out = np.zeros(len(src_true), np.bool_)
    _partner_kernel(_f64(src_true), np.ascontiguousarray(src_geom, dtype=np.int64), tp, geom,
                    np.ascontiguousarray(frame.valid.reshape(-1)), _f64(frame.R), _f64(frame.t).reshape(3),
                    float(K.f), float(K.cx), float(K.cy), int(K.width), int(K.height), float(tol) ** 2, out)
    return out


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _truth_maps(frame: DepthFrame) -> tuple[np.ndarray, np.ndarray]:
    """The frame's true points (H·W, 3) and geoms (H·W,) flat, as the kernels take them."""
    return _f64(frame.true_points).reshape(-1, 3), np.ascontiguousarray(frame.geom, dtype=np.int64).reshape(-1)


@njit(cache=True)
def _is_true(src_true, src_geom, tp, geom, i, j, tol2):
    """Source point i and pixel j: one geom, true positions closer than √tol2 (NaN: not)."""
    if geom[j] != src_geom[i]:
        return False
    dx, dy, dz = tp[j, 0] - src_true[i, 0], tp[j, 1] - src_true[i, 1], tp[j, 2] - src_true[i, 2]
    return dx * dx + dy * dy + dz * dz < tol2


@njit(cache=True)
def _true_pairs_kernel(src_true, src_geom, tp, geom, source, pixel, tol2, out):
    for k in range(source.shape[0]):
        out[k] = _is_true(src_true, src_geom, tp, geom, source[k], pixel[k], tol2)


@njit(cache=True)
def _partner_kernel(src_true, src_geom, tp, geom, valid, R, t, f, cx, cy, width, height, tol2, out):
    for i in range(src_true.shape[0]):
        dx, dy, dz = src_true[i, 0] - t[0], src_true[i, 1] - t[1], src_true[i, 2] - t[2]
        z = R[0, 2] * dx + R[1, 2] * dy + R[2, 2] * dz
        if not z > 0.0:   # also NaN
            continue
        u = np.rint(f * (R[0, 0] * dx + R[1, 0] * dy + R[2, 0] * dz) / z + cx)
        v = np.rint(f * (R[0, 1] * dx + R[1, 1] * dy + R[2, 1] * dz) / z + cy)
        if not (u >= 0.0 and u < width and v >= 0.0 and v < height):
            continue
        j = int(v) * width + int(u)
        out[i] = valid[j] and _is_true(src_true, src_geom, tp, geom, i, j, tol2)


def score_correspondences(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame, source: np.ndarray,
                          pixel: np.ndarray, tol: float) -> CorrespondenceScore:
    """Precision and recall of the pairs (``source``, ``pixel``) against the frame's truth."""
    return score_associations(src_true, src_geom, frame, [(source, pixel)], tol)[0]


def score_associations(src_true: np.ndarray, src_geom: np.ndarray, frame: DepthFrame,
                       associations: Sequence[tuple[np.ndarray, np.ndarray]], tol: float) -> list[CorrespondenceScore]:
    """``score_correspondences`` of several associations of one source set and frame (partners found
    once)."""
    partner = has_partner(src_true, src_geom, frame, tol)
    n_partner = int(partner.sum())
    tp, geom = _truth_maps(frame)
    truth, geoms = _f64(src_true), np.ascontiguousarray(src_geom, dtype=np.int64)
    scores = []
    for source, pixel in associations:
        right, recalled = _count_kernel(truth, geoms, tp, geom, partner, np.ascontiguousarray(source, dtype=np.int64),
                                        np.ascontiguousarray(pixel, dtype=np.int64), float(tol) ** 2)
        precision = float(right / len(source)) if len(source) else float("nan")
        recall = float(recalled / n_partner) if n_partner else float("nan")
        scores.append(CorrespondenceScore(len(source), int(right), n_partner, precision, recall))
    return scores


@njit(cache=True)
def _count_kernel(src_true, src_geom, tp, geom, partner, source, pixel, tol2):
    """(true pairs, source points with a partner in at least one true pair) of one association."""
    found = np.zeros(src_true.shape[0], np.bool_)
    right = recalled = 0
    for k in range(source.shape[0]):
        i = source[k]
        if _is_true(src_true, src_geom, tp, geom, i, pixel[k], tol2):
            right += 1
            if partner[i] and not found[i]:
                found[i] = True
                recalled += 1
    return right, recalled


def relative_pose_error(R0_true: np.ndarray, t0_true: np.ndarray, R1_true: np.ndarray, t1_true: np.ndarray,
                        R0_est: np.ndarray, t0_est: np.ndarray, R1_est: np.ndarray,
                        t1_est: np.ndarray) -> tuple[float, float]:
    """Translation (m) and rotation (deg) of ``Δ_true⁻¹ Δ_est``, ``Δ = T0⁻¹ T1``: one step's RPE."""
    dR_true, dt_true = R0_true.T @ R1_true, R0_true.T @ (t1_true - t0_true)
    dR_est, dt_est = R0_est.T @ R1_est, R0_est.T @ (t1_est - t0_est)
    trans = float(np.linalg.norm(dR_true.T @ (dt_est - dt_true)))
    return trans, float(rotation_errors_deg(dR_true[None], dR_est[None])[0])
