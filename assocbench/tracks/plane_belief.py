"""The open-loop problem of one frame of a robot in the plane with range-bearing point landmarks:
the sampled estimate predicts each mapped landmark, ``P = H Σ Hᵀ``; measurements are the detections
plus uniform clutter."""

from __future__ import annotations

import numpy as np

from ..association.problem import NO_MATCH, Problem
from ..association.truth import FrameTruth
from ..belief.config import BeliefConfig, map_mask, prediction_covariance, true_association
from ..belief.planar import (
    clutter_detections,
    in_sensor_view,
    nominal_noise,
    planar_pose_covariance,
    sample_planar_estimate,
)
from ..models.range_bearing import ANGULAR, jacobians, predict


def make_planar_problem(seq, frame: int, cfg: BeliefConfig, seed: int) -> tuple[Problem, FrameTruth]:
    """The open-loop problem and truth of one planar frame. ``seq`` has ``poses`` (N, 3), ``z``,
    ``R``, ``labels``, ``visible`` (N, L), ``landmarks`` (L, 2), ``max_range`` and ``fov`` (bounding
    the candidates) and ``nominal_R`` (a clutter detection's noise in a frame without detections)."""
    rng = np.random.default_rng([seed, frame, 101])
    pose_hat, map_hat = sample_planar_estimate(seq.poses[frame], seq.landmarks, cfg, rng)
    in_map = map_mask(len(seq.landmarks), cfg, seed)
    zhat = predict(pose_hat, map_hat)
    cand = np.flatnonzero(in_map & in_sensor_view(zhat, seq.max_range, seq.fov))
    H_pose, H_l = jacobians(pose_hat, map_hat[cand])
    z, R, labels = seq.z[frame], seq.R[frame], seq.labels[frame]
    cz, cR = clutter_detections(rng, cfg.clutter, nominal_noise(R, seq.nominal_R), seq.max_range, seq.fov)
    feature_labels = np.concatenate([np.where((labels >= 0) & in_map[np.maximum(labels, 0)], labels, NO_MATCH),
                                     np.full(cfg.clutter, NO_MATCH)]).astype(np.int64)
    problem = Problem(z=np.vstack([z.reshape(-1, 2), cz]), R=np.concatenate([R.reshape(-1, 2, 2), cR]),
                      zhat=zhat[cand], P=prediction_covariance(H_pose, H_l, planar_pose_covariance(cfg), cfg),
                      landmark_ids=cand, volume=seq.max_range * seq.fov, angular=ANGULAR)
    return problem, FrameTruth(feature_labels, true_association(feature_labels, cand), seq.visible[frame][cand])
