"""The dense track's settings sections ``depth``, ``icp``, ``fusion`` and ``dense``, each checked
when built, before anything renders."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import UserError
from ...validation import in_range, one_of, validate_fields

MAX_DOWNSAMPLE = 16


@dataclass(frozen=True)
class DepthConfig:
    """Settings of the depth sensor (section ``depth:``); all enter the cache key.

    downsample: keep pixel ``(s·i, s·j)``; the intrinsics become exactly
        ``K' = (W//s, H//s, f/s, cx/s, cy/s)``, so a kept pixel's ray is unchanged.
    sigma_base / sigma_quad: axial noise ``sigma(z) = sigma_base + sigma_quad · z²`` (m, 1/m).
    grazing_deg: a pixel whose view ray meets the surface more than this from its normal drops out.
    dropout: extra share of pixels dropped at random.
    min_depth / max_depth: the working range (m); a depth outside it is missing.
    normal_smooth_px: sigma (px) of the edge-aware Gaussian (``depth_smoothing``) applied to the
        depth the NORMALS come from (vertices keep the raw depth; 0: no smoothing). Raw
        neighbour-difference normals are tens of degrees off at 320x240; 3 px is the narrowest width
        at which ICP registered crates frames 11 cm / 7 deg apart.
    """

    downsample: int = field(default=2, metadata=in_range(1, MAX_DOWNSAMPLE, unit="px (stride)"))
    sigma_base: float = field(default=0.0012, metadata=in_range(0, 1, unit="m"))
    sigma_quad: float = field(default=0.0019, metadata=in_range(0, 1, unit="1/m"))
    grazing_deg: float = field(default=75.0, metadata=in_range(0, 90, lo_open=True, unit="deg"))
    dropout: float = field(default=0.0, metadata=in_range(0, 1, hi_open=True, unit="dimensionless"))
    min_depth: float = field(default=0.2, metadata=in_range(0, None, lo_open=True, unit="m"))
    max_depth: float = field(default=8.0, metadata=in_range(0, None, lo_open=True, unit="m"))
    normal_smooth_px: float = field(default=3.0, metadata=in_range(0, 10, unit="px"))

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """One-line ``UserError`` naming the bad setting (``depth.<field>``) and what it accepts."""
        validate_fields(self, "depth")
        if self.min_depth >= self.max_depth:
            raise UserError(f"depth.min_depth ({self.min_depth}) must be below depth.max_depth "
                            f"({self.max_depth}): the sensor's working range would be empty")
        if 0 < self.normal_smooth_px < MIN_SMOOTH_PX:   # a Gaussian this narrow weighs no neighbour: no smoothing
            raise UserError(f"depth.normal_smooth_px must be 0 (no smoothing) or at least {MIN_SMOOTH_PX} px, "
                            f"got {self.normal_smooth_px}")

    def sigma(self, z: np.ndarray) -> np.ndarray:
        """Axial noise ``sigma(z) = sigma_base + sigma_quad · z²`` (m) at depth ``z`` (m)."""
        # the compiled pass's own formula, run by numpy: the same values, and nothing to compile for a new input type
        from .sensor_passes import axial_sigma

        return axial_sigma.py_func(np.asarray(z, dtype=np.float64), self.sigma_base, self.sigma_quad)


MIN_SMOOTH_PX = 0.1   # below it exp(-1/(2σ²)) < 1e-21: the neighbours' weights vanish (and 1/σ² overflows)


@dataclass(frozen=True)
class IcpConfig:
    """Settings of ``icp`` (section ``icp:``); the thresholds' evidence is
    ``benchmarks/dense_icp_thresholds.py`` and ``dense_direction_share.py``.

    max_iterations: iterations at most; no convergence by then is a failure.
    converge_rot_deg / converge_trans: converged when an update rotates less than this (deg) and
        moves less than this (m).
    min_pairs: fewer pairs in any iteration is a failure (too little to constrain 6 dof).
    min_inlier_share: final pairs / considered (``Pairs.considered``) below this is a failure; gross
        failure only.
    min_direction_share: the final pairs' share of the visible points' information in the worst-kept
        motion (``direction_share``) below this is a failure: a slide that lost the surfaces fixing
        some motion (bays' side walls).
    max_rms: final gated point-to-plane residual rms (m) above this is a failure; gross mismatch
        only.
    max_condition: κ(S) (``stability_transform``) above this is a failure: some motion is
        unconstrained.
    max_step_m / max_step_deg: a camera moved farther (m) or turned more (deg) than this from the
        guess is a failure: past the capture range a converged pose is as likely wrong.
    """

    max_iterations: int = field(default=100, metadata=in_range(1, 10_000, unit="iterations"))
    converge_rot_deg: float = field(default=5e-3, metadata=in_range(0, 180, lo_open=True, unit="deg"))
    converge_trans: float = field(default=1e-4, metadata=in_range(0, None, lo_open=True, unit="m"))
    min_pairs: int = field(default=200, metadata=in_range(6, None, unit="pairs"))
    min_inlier_share: float = field(default=0.5, metadata=in_range(0, 1, unit="dimensionless"))
    min_direction_share: float = field(default=0.25, metadata=in_range(0, 1, unit="dimensionless"))
    max_rms: float = field(default=0.02, metadata=in_range(0, None, lo_open=True, unit="m"))
    max_condition: float = field(default=1000.0, metadata=in_range(1, None, unit="dimensionless"))
    max_step_m: float = field(default=0.15, metadata=in_range(0, None, lo_open=True, unit="m"))
    max_step_deg: float = field(default=10.0, metadata=in_range(0, 180, lo_open=True, unit="deg"))

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """One-line ``UserError`` naming ``icp.<field>`` for a bad value."""
        validate_fields(self, "icp")


@dataclass(frozen=True)
class FusionConfig:
    """Settings of point-based fusion (section ``fusion:``).

    d_thr: pass 2's distance gate |p − q| (m); also the see-through outlier test's margin.
    angle_deg: pass 2's normal gate (deg; 180: off). It needs smoothed normals: on raw ones a 20°
        gate refuses most pairs and biases the rest.
    dormant_frames: an unstable point not merged for this many frames is removed.
    stable_weight: a point with at least this weight (merges + 1) is stable: never removed.
    remove_dormant / remove_outliers: the homework bonus's two removals (false: keep everything).
    voxel: one map point per cell of this size (m) and normal class (``voxel_table``), so the map's
        size plateaus; 0: the homework's rule (every unmerged pixel is added). 1 cm is the pixel
        footprint at 2 m at 320x240; coarser cells thin ICP's source until frames fail
        ``icp.max_condition``.
    """

    d_thr: float = field(default=0.05, metadata=in_range(0, 10, lo_open=True, unit="m"))
    angle_deg: float = field(default=20.0, metadata=in_range(0, 180, lo_open=True, unit="deg"))
    dormant_frames: int = field(default=20, metadata=in_range(1, 10**9, unit="frames"))
    stable_weight: int = field(default=3, metadata=in_range(1, 10**9, unit="merges + 1"))
    remove_dormant: bool = True
    remove_outliers: bool = True
    voxel: float = field(default=0.01, metadata=in_range(0, 10, unit="m"))

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """One-line UserError naming the first bad field (``fusion.d_thr must be ...``)."""
        validate_fields(self, "fusion")


TRACKING = ("model", "frame", "truth")
PREDICTION = ("view", "map")


@dataclass(frozen=True)
class DenseConfig:
    """Section ``dense:``: how frames are tracked and how truth is judged.

    tracking: model (the fused map), frame (the previous frame's points) or truth (the map fused at
        true poses, ICP from the previous true pose: one step's error without drift).
    prediction: the map as ICP's source: view (rendered into the predicted view, one point a pixel,
        ``tracks.dense.prediction``) or map (every point, the homework's; costs the map's size an
        iteration).
    index: splat and fuse only the map's blocks in the view frustum: the same numbers bit for bit,
        at a cost that follows the view; false visits every point (``benchmarks/dense_rate.py``'s
        baseline).
    truth_tol: a pair is true when map point and pixel lie on one geom with true positions this
        close (m).
    path_frames: the camera path is laid out over this many frames; a run takes its first ones.
    """

    tracking: str = field(default="model", metadata=one_of(*TRACKING))
    prediction: str = field(default="view", metadata=one_of(*PREDICTION))
    index: bool = True
    truth_tol: float = field(default=0.03, metadata=in_range(0, 1, lo_open=True, unit="m"))
    path_frames: int = field(default=200, metadata=in_range(2, None, unit="frames"))

    def __post_init__(self) -> None:
        validate_fields(self, "dense")
