"""Belief of the camera track: estimate = truth + error drawn from the reported covariance Σ.

The filter reports Σ = blockdiag(σ_p² I₃, σ_θ² I₃, Σ_L) over camera position, orientation and
landmark positions, with ``Σ_L = σ_l² I + σ_c² (11ᵀ ⊗ I₃)`` (optional common-mode error
shared by all landmarks). The actual error is drawn from ``k² Σ`` (``k = miscalibration``),
so gating theory holds at ``k = 1`` and difficulty is a knob. The predicted bundle covariance
is ``P = J Σ Jᵀ`` with the analytic Jacobians of ``pinhole.predict_bundle``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.problem import NO_MATCH, Problem
from ..validation import in_range, validate_fields
from ..sim.sequence import Sequence
from .pinhole import perturb_pose, predict_bundle


@dataclass(frozen=True)
class BeliefConfig:
    """Difficulty knobs of the belief.

    sigma_position: camera position std (m).    sigma_rotation: camera orientation std (deg).
    sigma_landmark: independent landmark position std (m).
    sigma_common: std of an error shared by all landmarks (m): correlated map error.
    sigma_pixel: reported measurement noise std (px); R_i = σ² I.
    miscalibration: k; the actual error is drawn from k²Σ while Σ is reported.
    map_fraction: share of the scene's landmarks that are in the map (others are clutter).
    clutter: extra features drawn uniformly over the image per frame.
    max_view_angle: candidates must face the estimated camera within this angle (deg).
    """

    sigma_position: float = field(default=0.03, metadata=in_range(0))
    sigma_rotation: float = field(default=0.5, metadata=in_range(0, 90))
    sigma_landmark: float = field(default=0.02, metadata=in_range(0))
    sigma_common: float = field(default=0.0, metadata=in_range(0))
    sigma_pixel: float = field(default=1.0, metadata=in_range(0, lo_open=True))
    miscalibration: float = field(default=1.0, metadata=in_range(0, lo_open=True))
    map_fraction: float = field(default=1.0, metadata=in_range(0, 1))
    clutter: int = field(default=0, metadata=in_range(0))
    max_view_angle: float = field(default=75.0, metadata=in_range(0, 90, lo_open=True))

    def __post_init__(self) -> None:
        validate_fields(self, "belief")

    @property
    def pose_covariance(self) -> np.ndarray:
        """Σ of ``[δp, δθ]`` (6, 6), rotation in radians."""
        return np.diag([self.sigma_position**2] * 3 + [np.deg2rad(self.sigma_rotation) ** 2] * 3)


@dataclass(frozen=True)
class FrameTruth:
    """Truth of one problem: ``feature_labels`` (m,) map id or -1; ``association`` (n,) the true
    feature of each candidate or -1; ``visible`` (n,) whether each candidate is really visible."""

    feature_labels: np.ndarray
    association: np.ndarray
    visible: np.ndarray


def map_mask(n_landmarks: int, cfg: BeliefConfig, seed: int) -> np.ndarray:
    """Which landmarks are in the map (fixed per seed, not per frame)."""
    rng = np.random.default_rng([seed, 202])
    keep = np.zeros(n_landmarks, bool)
    keep[rng.permutation(n_landmarks)[: int(round(cfg.map_fraction * n_landmarks))]] = True
    return keep


def bundle_covariance(J_pose: np.ndarray, J_l: np.ndarray, cfg: BeliefConfig) -> np.ndarray:
    """``P = J Σ Jᵀ`` (2n, 2n) of the camera's 6-dof pose and 3-D landmarks (``prediction_covariance``)."""
    return prediction_covariance(J_pose, J_l, cfg.pose_covariance, cfg)


def prediction_covariance(J_pose: np.ndarray, J_l: np.ndarray, Sigma_pose: np.ndarray, cfg: BeliefConfig) -> np.ndarray:
    """``P = J Σ Jᵀ`` (nd, nd) for ``J_pose`` (n, d, q) and ``J_l`` (n, d, s), exploiting Σ's
    structure: the pose block ``Sigma_pose`` (q, q), independent landmarks ``σ_l² I`` and the
    common-mode term ``σ_c² (11ᵀ ⊗ I_s)``; any track's dimensions."""
    n, d, s = J_l.shape
    Jp = J_pose.reshape(d * n, J_pose.shape[2])
    P = Jp @ Sigma_pose @ Jp.T
    block = cfg.sigma_landmark**2 * np.einsum("nab,ncb->nac", J_l, J_l)
    idx = np.arange(n)
    P.reshape(n, d, n, d)[idx, :, idx, :] += block
    if cfg.sigma_common > 0:
        G = J_l.reshape(d * n, s)
        P += cfg.sigma_common**2 * G @ G.T
    return 0.5 * (P + P.T)


def sample_estimate(R, p, landmarks, cfg: BeliefConfig, rng: np.random.Generator):
    """Estimated ``(R̂, p̂, l̂)``: truth perturbed by an error drawn from ``k² Σ``."""
    k = cfg.miscalibration
    e_pose = rng.normal(0.0, 1.0, 6) * np.sqrt(np.diag(cfg.pose_covariance)) * k
    e_lm = rng.normal(0.0, cfg.sigma_landmark * k, landmarks.shape)
    e_lm += rng.normal(0.0, cfg.sigma_common * k, 3)
    R_hat, p_hat = perturb_pose(R, p, e_pose[:3], e_pose[3:])
    return R_hat, p_hat, landmarks + e_lm


def expected_in_view(seq: Sequence, p_hat: np.ndarray, l_hat: np.ndarray, h: np.ndarray, depth: np.ndarray,
                     max_view_angle: float) -> np.ndarray:
    """Landmarks the estimate expects to see: in front, facing the estimated camera within
    ``max_view_angle`` and predicted inside the image (the estimate knows nothing of occlusion)."""
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


def true_association(feature_labels: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """(n,) index of the feature labelled with each candidate landmark, or -1."""
    out = np.full(len(candidates), NO_MATCH, dtype=np.int64)
    where = {int(lm): i for i, lm in enumerate(feature_labels) if lm >= 0}
    for c, lm in enumerate(candidates):
        out[c] = where.get(int(lm), NO_MATCH)
    return out


def with_clutter_labels(labels: np.ndarray, clutter: int, in_map: np.ndarray | None) -> np.ndarray:
    """Feature labels of a frame's truth (open and closed loop, every track): the sensor's label (-1 for look-alikes), -1 for a
    landmark outside the map in localisation, then -1 for each clutter feature."""
    if in_map is not None:
        labels = np.where((labels >= 0) & in_map[np.maximum(labels, 0)], labels, NO_MATCH)
    return np.concatenate([labels, np.full(clutter, NO_MATCH)]).astype(np.int64)
