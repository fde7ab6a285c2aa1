"""The dense track's settings sections: ``depth`` (the depth sensor), ``icp`` (point-to-plane ICP),
``fusion`` (point-based fusion) and ``dense`` (what is tracked and how truth is judged). Each
value is checked when its section is built, before anything renders."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import UserError
from ...validation import in_range, one_of, validate_fields

MAX_DOWNSAMPLE = 16


@dataclass(frozen=True)
class DepthConfig:
    """Settings of the depth sensor (section ``depth:`` of a run config); all enter the cache key.

    downsample: keep pixel ``(s·i, s·j)``; the intrinsics become exactly
        ``K' = (W//s, H//s, f/s, cx/s, cy/s)``, so a kept pixel's ray is unchanged.
    sigma_base, sigma_quad: axial noise ``sigma(z) = sigma_base + sigma_quad · z²`` (m, 1/m).
    grazing_deg: a pixel whose view ray meets the surface more than this from its normal drops out.
    dropout: extra share of pixels dropped at random.
    min_depth, max_depth: the working range (m); a measured depth outside it is missing.
    normal_smooth_px: sigma (px) of the edge-aware Gaussian (``depth_smoothing``) that smooths
        the depth the NORMALS are computed from (vertices keep the raw depth); 0 takes normals from
        the raw depth. At 320x240 the default noise is about the spacing of neighbouring vertices,
        so raw neighbour-difference normals are off by a median 43-64 deg at 1-4 m. On crates
        frame 50 (noise as default; measured with the 2-D window the separable filter replaced, which
        gives 1.5 deg at 3 px too) the median error is 2.9 deg at 2 px and 1.5 deg at 3 px, and
        ICP from the identity registered two crates frames 11 cm / 7 deg apart only at 3 px
        (0.15 mm / 0.013 deg; at 2 px it slid 13 cm off): the default is 3.
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
    """Settings of ``icp`` (the ``icp:`` section of a run config).

    max_iterations: iterations at most; no convergence by then is a failure.
    converge_rot_deg / converge_trans: converged when one update rotates less than this (deg)
        and moves less than this (m).
    min_pairs: fewer pairs in any iteration is a failure (too little to constrain 6 dof).
    min_inlier_share: final pairs / considered (``Pairs.considered``) below this is a failure.
    min_direction_share: the final pairs' share of the information of the visible source points
        in the worst-kept motion (``direction_share``) below this is a failure: the pose slid to
        where the surfaces that fix some motion find no partner (a wrong minimum of self-similar
        geometry, e.g. bays' side walls lost after a sideways slide).
    max_rms: final point-to-plane residual rms (m, each residual scaled by the gate's floor over
        its gate: the module docstring's **Failure**) above this is a failure.
    max_condition: κ(S) (the normal matrix in comparable units, ``stability_transform``) of the
        last iteration above this is a failure: some motion is unconstrained (a single plane, a
        corridor's axis).
    max_step_m / max_step_deg: an estimate whose camera moved farther than this (m) or turned
        more than this (deg) from the initial guess is a failure: beyond ICP's capture range a
        converged pose is as likely a wrong minimum (one period of self-similar geometry off)
        as the right one.

    The thresholds' defaults and their evidence: see the module docstring.
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
    """Settings of point-based fusion (the ``fusion:`` section of a run config).

    d_thr: pass 2's distance gate |p − q| (m); also the margin of the see-through outlier test.
    angle_deg: pass 2's normal gate, the angle between map and frame normals (deg); 180 turns it
        off. It needs smooth normals: ``normal_map`` of raw depth with σ(z) = 0.0012 + 0.0019 z² at
        320x240 is off by 58° (median) at 2-3 m, so a 20° gate refuses ~90 % of the pairs and biases
        what it keeps (a point merges with the samples whose noise tilts the normal its own way):
        the map is then no better than one frame. Normals of the depth box-filtered 5x5 with a ±2 px
        stencil (median 5° off) work at 20° (tests/test_point_fusion.py has both).
    dormant_frames: an unstable point not merged for this many frames is removed.
    stable_weight: a point with at least this weight (merges + 1) is stable: never removed.
    remove_dormant / remove_outliers: the homework bonus's two removals (false: keep everything).
    voxel: one map point per cell of this size (m) and normal class (``voxel_table``): a pixel no
        map point merged with merges into the point holding its cell instead of being added, so the
        map's density is bounded and its size plateaus once the scene is seen. 0: the homework's
        rule (every such pixel is added; the map grows with every new viewpoint). 1 cm is the
        pixel footprint z/f at 2 m at 320x240 with a 60° field of view (f = 208 px), the near
        half of the crates and bays paths' depths; the cell is ``d_thr`` thick along the normal's
        dominant axis (``voxel_table``). Coarser cells thin the model rendered into the view, ICP's
        source, and with it its conditioning: at 2 cm crates seed 1 lost 3 of 40 frames
        frame-to-model (κ 1 060-1 400 > ``icp.max_condition``). Crates, 200 frames
        frame-to-model (map points, ATE, map error median/p95): 1 cm 108k, 1.4 mm, 0.43/3.5 mm;
        the homework's rule 1.7 mm, 0.36/2.9 mm (docs/tracks/dense.md).
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

    tracking: what ICP registers each frame to: model (the fused map, the homework's frame-to-model),
        frame (the previous frame's points, frame-to-frame) or truth (the map fused at the true
        poses, ICP from the previous true pose: one step's error without drift).
    prediction: the map as ICP's source when tracking the model or the truth, either view (the map
        rendered into the predicted view, one point a pixel, KinectFusion's predicted maps, see
        ``tracks.dense.prediction``; an ICP iteration costs the pixel count) or map (every map
        point, the homework's whole-map projection; an ICP iteration costs the map's size).
    index: splat and fuse only the map's blocks whose bounding box meets the view frustum (the map's
        index, ``tracks.dense.fusion``): the same numbers bit for bit, a per-frame cost that follows
        what is in view; false visits every map point in every frame (the whole-map baseline that
        ``benchmarks/dense_rate.py`` times).
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
