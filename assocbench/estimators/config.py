"""Settings of the closed loop's estimator (the ``estimator:`` section of a run config)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..validation import in_range, one_of, validate_fields

MODES = ("localisation", "slam")
ESTIMATOR_NAMES = ("ekf", "isam2")
INITIALISERS = ("depth", "triangulation")


@dataclass(frozen=True)
class EstimatorConfig:
    """How the closed loop estimates.

    name: ``ekf`` (the track's EKF-SLAM) or ``isam2`` (planar track: GTSAM iSAM2; the ``gtsam``
        extra).
    mode: ``localisation`` (the map starts at the belief's estimate) or ``slam`` (the map starts
        empty; unassociated features become landmarks).
    odometry_sigma_translation / odometry_sigma_rotation: σ per axis of the odometry noise per frame
        (m, deg); Q = diag(σ_t² I₃, σ_r² I₃).
    odometry_miscalibration: k; the actual odometry noise is drawn with k σ while σ is reported.
    init: how ``slam`` makes a landmark: ``depth`` (RGB-D depth plus noise) or ``triangulation``
        (two views by DLT, ``two_view_init``).
    depth_sigma / depth_sigma_quadratic: RGB-D depth noise σ_z(z) = σ₀ + k z² (m, 1/m).
    confirm_after: a new landmark is tentative until observed this many times (its first included).
    drop_after: a tentative landmark predicted in view and left unassociated this many times is
        removed.
    target_paired: slam makes landmarks only while fewer features than this were paired in the frame
        (at most the shortfall).
    max_new_per_frame / max_landmarks: caps on landmark creation, keeping the state tractable.
    new_landmark_gate: an unassociated feature makes a landmark only when its Mahalanobis distance
        (σ units) to every candidate exceeds this; 0: all; null: the track's (camera 0, planar 4).
        Without it a strict method's misses become duplicates.
    pixel_noise: add N(0, σ_pixel² I) to every feature after labelling, so the filter's R is the
        noise it gets; false leaves the detector's own error (the filter is then conservative).
    """

    name: str = field(default="ekf", metadata=one_of(*ESTIMATOR_NAMES))
    mode: str = field(default="localisation", metadata=one_of(*MODES))
    odometry_sigma_translation: float = field(default=0.01, metadata=in_range(0, 10, unit="m"))
    odometry_sigma_rotation: float = field(default=0.2, metadata=in_range(0, 90, unit="deg"))
    odometry_miscalibration: float = field(default=1.0, metadata=in_range(0, 100, lo_open=True, unit="dimensionless"))
    init: str = field(default="depth", metadata=one_of(*INITIALISERS))
    depth_sigma: float = field(default=0.002, metadata=in_range(0, 1, unit="m"))
    depth_sigma_quadratic: float = field(default=0.002, metadata=in_range(0, 1, unit="1/m"))
    confirm_after: int = field(default=2, metadata=in_range(1, 1000, unit="observations"))
    drop_after: int = field(default=2, metadata=in_range(1, 1000, unit="misses"))
    target_paired: int = field(default=15, metadata=in_range(0, 1000, unit="features"))
    max_new_per_frame: int = field(default=10, metadata=in_range(0, 1000, unit="landmarks per frame"))
    max_landmarks: int = field(default=300, metadata=in_range(1, 5000, unit="landmarks"))
    new_landmark_gate: float | None = field(default=None, metadata=in_range(0, 1000, unit="σ (Mahalanobis distance)"))
    pixel_noise: bool = True

    def __post_init__(self) -> None:
        validate_fields(self, "estimator")

    @property
    def odometry_covariance(self) -> np.ndarray:
        """Q (6, 6) of the increment ``[δp, δθ]`` reported to the filter, rotation in radians."""
        return np.diag([self.odometry_sigma_translation ** 2] * 3
                       + [np.deg2rad(self.odometry_sigma_rotation) ** 2] * 3)

    @property
    def planar_odometry_covariance(self) -> np.ndarray:
        """Q (3, 3) of a planar increment ``[Δx, Δy, Δθ]`` reported to the filter: diag(σ_t², σ_t², σ_r²),
        heading in radians."""
        return np.diag([self.odometry_sigma_translation ** 2] * 2 + [np.deg2rad(self.odometry_sigma_rotation) ** 2])

    def depth_std(self, z: np.ndarray) -> np.ndarray:
        """σ_z(z) = σ₀ + k z² (a structured-light sensor's axial noise grows with depth squared)."""
        return self.depth_sigma + self.depth_sigma_quadratic * np.asarray(z) ** 2
