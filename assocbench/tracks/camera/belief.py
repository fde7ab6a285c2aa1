"""Belief of the camera track: the truth plus an error drawn from ``k² Σ`` while Σ = blockdiag(σ_p²
I₃, σ_θ² I₃, Σ_L), ``Σ_L = σ_l² I + σ_c² (11ᵀ ⊗ I₃)``, is reported (``k = miscalibration``: gating
theory holds at 1). ``P = J Σ Jᵀ`` with ``pinhole.predict_bundle``'s Jacobians.
"""

from __future__ import annotations

import numpy as np

from ...association.problem import NO_MATCH, Problem
from ...association.truth import FrameTruth
from ...belief.config import BeliefConfig, map_mask, prediction_covariance, sample_estimate, true_association
from ...models.pinhole import predict_bundle
from .sequence import Sequence


def bundle_covariance(J_pose: np.ndarray, J_l: np.ndarray, cfg: BeliefConfig) -> np.ndarray:
    """``P = J Σ Jᵀ`` (2n, 2n) of the camera's 6-dof pose and 3-D landmarks (``prediction_covariance``)."""
    return prediction_covariance(J_pose, J_l, cfg.pose_covariance, cfg)


def expected_in_view(seq: Sequence, p_hat: np.ndarray, l_hat: np.ndarray, h: np.ndarray, depth: np.ndarray,
                     max_view_angle: float) -> np.ndarray:
    """Landmarks the estimate expects to see: in front, facing it within ``max_view_angle``,
    predicted in the image (occlusion unknown to it)."""
    to_cam = p_hat - l_hat
    cos_view = np.einsum("ij,ij->i", seq.normals, to_cam) / np.linalg.norm(to_cam, axis=1)
    in_image = seq.K.in_image(np.nan_to_num(h, nan=-1e9))
    return (depth > 1e-3) & (cos_view > np.cos(np.deg2rad(max_view_angle))) & in_image


def make_problem(seq: Sequence, frame: int, cfg: BeliefConfig, seed: int) -> tuple[Problem, FrameTruth]:
    """The association problem of one frame and its truth."""
    rng = np.random.default_rng([seed, frame, 101])
    R_hat, p_hat, l_hat = sample_estimate(seq.rotations[frame], seq.positions[frame], seq.landmarks, cfg, rng)
    in_map = map_mask(len(seq.landmarks), cfg, seed)
    h, J_pose, J_l, depth = predict_bundle(R_hat, p_hat, l_hat, seq.K)
    cand = np.flatnonzero(in_map & expected_in_view(seq, p_hat, l_hat, h, depth, cfg.max_view_angle))
    features, labels = seq.features[frame], seq.labels[frame]
    clutter = rng.uniform([-0.5, -0.5], [seq.K.width - 0.5, seq.K.height - 0.5], (cfg.clutter, 2))
    z = np.vstack([features, clutter]) if cfg.clutter else features
    feature_labels = np.concatenate([np.where((labels >= 0) & in_map[np.maximum(labels, 0)], labels, NO_MATCH),
                                     np.full(cfg.clutter, NO_MATCH)]).astype(np.int64)
    problem = Problem(
        z=z, R=np.repeat((cfg.sigma_pixel**2 * np.eye(2))[None], len(z), axis=0),
        zhat=h[cand], P=bundle_covariance(J_pose[cand], J_l[cand], cfg), landmark_ids=cand,
        volume=seq.K.area,
    )
    return problem, FrameTruth(feature_labels, true_association(feature_labels, cand), seq.visible[frame][cand])


