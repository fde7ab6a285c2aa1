"""The open-loop belief's difficulty knobs and sampling: the estimate is the truth plus an error
drawn from ``k² Σ`` while Σ is reported (``k = miscalibration``), so gating theory holds at
``k = 1``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..association.problem import NO_MATCH
from ..models.pinhole import perturb_pose
from ..validation import in_range, validate_fields

MAX_SIGMA_M = 1000.0
MIN_SIGMA_PIXEL, MAX_SIGMA_PIXEL = 1e-6, 1e4
MAX_MISCALIBRATION = 1000.0


@dataclass(frozen=True)
class BeliefConfig:
    """Difficulty knobs of the belief.

    sigma_position: camera position std (m).
    sigma_rotation: camera orientation std (deg).
    sigma_landmark: independent landmark position std (m).
    sigma_common: std of an error shared by all landmarks (m): correlated map error.
    sigma_pixel: reported measurement noise std (px); R_i = σ² I.
    miscalibration: k; the actual error is drawn from k²Σ while Σ is reported.
    map_fraction: share of the scene's landmarks that are in the map (others are clutter).
    clutter: extra features drawn uniformly over the image per frame.
    max_view_angle: candidates must face the estimated camera within this angle (deg).
    """

    # at most MAX_SIGMA_M, and k at most MAX_MISCALIBRATION: a std of 1e300 squared overflows (an
    # OverflowError in the worker), and an estimate a kilometre off sees no landmark of any scene
    sigma_position: float = field(default=0.03, metadata=in_range(0, MAX_SIGMA_M, unit="m"))
    sigma_rotation: float = field(default=0.5, metadata=in_range(0, 90, unit="deg"))
    sigma_landmark: float = field(default=0.02, metadata=in_range(0, MAX_SIGMA_M, unit="m"))
    sigma_common: float = field(default=0.0, metadata=in_range(0, MAX_SIGMA_M, unit="m"))
    # at least MIN_SIGMA_PIXEL: 1e-300 squares to 0, a singular R; at most MAX_SIGMA_PIXEL, many images wide
    sigma_pixel: float = field(default=1.0, metadata=in_range(MIN_SIGMA_PIXEL, MAX_SIGMA_PIXEL, unit="px"))
    miscalibration: float = field(default=1.0, metadata=in_range(0, MAX_MISCALIBRATION, lo_open=True,
                                                                 unit="dimensionless"))
    map_fraction: float = field(default=1.0, metadata=in_range(0, 1, unit="dimensionless"))
    clutter: int = field(default=0, metadata=in_range(0, unit="features per frame"))
    max_view_angle: float = field(default=75.0, metadata=in_range(0, 90, lo_open=True, unit="deg"))

    def __post_init__(self) -> None:
        validate_fields(self, "belief")

    @property
    def pose_covariance(self) -> np.ndarray:
        """Σ of ``[δp, δθ]`` (6, 6), rotation in radians."""
        return np.diag([self.sigma_position**2] * 3 + [np.deg2rad(self.sigma_rotation) ** 2] * 3)


def sample_estimate(R: np.ndarray, p: np.ndarray, landmarks: np.ndarray, cfg: BeliefConfig,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Estimated ``(R̂, p̂, l̂)`` of a camera and ``landmarks`` (n, 3): the truth plus an error
    drawn from ``k² Σ`` (pose ``[δp, δθ]`` as ``pinhole.perturb_pose`` applies it)."""
    k = cfg.miscalibration
    e_pose = rng.normal(0.0, 1.0, 6) * np.sqrt(np.diag(cfg.pose_covariance)) * k
    e_lm = rng.normal(0.0, cfg.sigma_landmark * k, landmarks.shape)
    e_lm += rng.normal(0.0, cfg.sigma_common * k, 3)
    R_hat, p_hat = perturb_pose(R, p, e_pose[:3], e_pose[3:])
    return R_hat, p_hat, landmarks + e_lm


def map_mask(n_landmarks: int, cfg: BeliefConfig, seed: int) -> np.ndarray:
    """Which landmarks are in the map (fixed per seed, not per frame)."""
    rng = np.random.default_rng([seed, 202])
    keep = np.zeros(n_landmarks, bool)
    keep[rng.permutation(n_landmarks)[: int(round(cfg.map_fraction * n_landmarks))]] = True
    return keep


def prediction_covariance(J_pose: np.ndarray, J_l: np.ndarray, Sigma_pose: np.ndarray, cfg: BeliefConfig) -> np.ndarray:
    """``P = J Σ Jᵀ`` (nd, nd) for ``J_pose`` (n, d, q) and ``J_l`` (n, d, s), using Σ's structure:
    pose block ``Sigma_pose``, independent ``σ_l² I`` and common-mode ``σ_c² (11ᵀ ⊗ I_s)``."""
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


def true_association(feature_labels: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """(n,) index of the feature labelled with each candidate landmark, or -1."""
    out = np.full(len(candidates), NO_MATCH, dtype=np.int64)
    where = {int(lm): i for i, lm in enumerate(feature_labels) if lm >= 0}
    for c, lm in enumerate(candidates):
        out[c] = where.get(int(lm), NO_MATCH)
    return out


def with_clutter_labels(labels: np.ndarray, clutter: int, in_map: np.ndarray | None) -> np.ndarray:
    """A frame's feature labels: the sensor's (-1 for look-alikes), -1 for a landmark outside the
    map in localisation, then -1 per clutter feature."""
    if in_map is not None:
        labels = np.where((labels >= 0) & in_map[np.maximum(labels, 0)], labels, NO_MATCH)
    return np.concatenate([labels, np.full(clutter, NO_MATCH)]).astype(np.int64)
