"""The dense associator interface: pair source points (world) with pixels of a depth frame.

A source set is a map's points or a previous frame's points in WORLD coordinates: ``points`` and
unit ``normals`` (n, 3). A target is a ``DepthFrame`` and a guess ``(R, t)`` of its camera-to-world
pose. A pair (i, pixel) is kept only when it passes the homework's filters, all in world
coordinates with ``q = R V[pixel] + t`` and ``n_q = R N[pixel]``:

    target pixel valid (finite depth and normal),  |p_i − q| < gate(d),  angle(n_p, n_q) < angle_deg

(the angle test is ``n_p · n_q > cos(angle_deg)``). How the candidate pixel is found is the
method's: the projection of ``p_i`` under the guess (``projective``) or its nearest valid vertex
in 3-D (``kdtree``). NaN anywhere in a candidate fails every comparison, so it never pairs.

**The gate** grows with the depth noise of the pixel's measured depth ``d``:

    gate(d) = max(d_thr, gate_sigmas · σ(d)),   σ(d) = sigma_base + sigma_quad · d²

(the sensor's model, ``tracks.dense.depth_sensor.DepthConfig.sigma``; a dense run passes its own). ``d_thr``
is the floor, which covers the pose guess's error (ICP's capture range, see ``tracks.dense.icp``);
``gate_sigmas · σ`` the measurement's own scatter where it is larger: with the default noise σ is
3 mm at 1 m but 32 mm at 4 m, where a fixed 5 cm gate cut true pairs at 1.6 σ. With the defaults
(5 cm, 3 σ) the gate grows beyond the floor from 2.9 m on (9.5 cm at 4 m); 0 sigmas is the fixed
gate.

**Visible** source points are the ``considered`` ones (the denominator of ICP's inlier share):
in front of the camera, projecting into the image, and not hidden, i.e. not farther along the
ray than the pixel's measured surface by more than the gate (``z ≤ d + gate(d)``): a map point
behind a closer surface cannot be seen, so it is neither a pair nor a miss. A point in FRONT of
the measured surface by more than the gate is visible (the sensor sees through where it should
be): it counts, unpaired.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numba import njit

from ...errors import UserError
from ...models.depth_frame import DepthFrame
from ...validation import in_range, validate_fields

# the depth sensor's default axial noise (tracks.dense.depth_sensor.DepthConfig; a test keeps them equal),
# the gate's default; a dense run passes its own sensor's noise (tracks.dense.track)
SENSOR_SIGMA_BASE, SENSOR_SIGMA_QUAD = 0.0012, 0.0019


@dataclass
class Pairs:
    """An association: ``source`` (k,) int64 indices into the source points, ascending, each at
    most once; ``pixel`` (k,) int64 flat pixel indices ``v·W + u`` into the frame; ``considered``
    the source points that passed the method's first filter (see the method), so that
    ``len / considered`` is the share of visible points (module docstring) the filters kept."""

    source: np.ndarray
    pixel: np.ndarray
    considered: int

    def __len__(self) -> int:
        return len(self.source)

    @classmethod
    def empty(cls, considered: int = 0) -> Pairs:
        return cls(np.empty(0, np.int64), np.empty(0, np.int64), int(considered))


@dataclass
class DenseAssociator(ABC):
    """Base class. ``d_thr`` (m, > 0): the floor of the distance gate |p − q| < gate(d) of a pair;
    ``gate_sigmas`` (≥ 0), ``sigma_base`` (m), ``sigma_quad`` (1/m): its growth with the pixel's
    depth noise (module docstring); ``angle_deg`` (in (0, 180]): largest angle between the normals
    of a pair. Checked when built (a bad value is a one-line ``UserError`` naming ``params.<field>``)."""

    name: ClassVar[str] = "base"
    summary: ClassVar[str] = ""

    d_thr: float = field(default=0.05, metadata=in_range(0, None, lo_open=True))
    angle_deg: float = field(default=30.0, metadata=in_range(0, 180, lo_open=True))
    gate_sigmas: float = field(default=3.0, metadata=in_range(0, 100))
    sigma_base: float = field(default=SENSOR_SIGMA_BASE, metadata=in_range(0, 1))
    sigma_quad: float = field(default=SENSOR_SIGMA_QUAD, metadata=in_range(0, 1))

    def __post_init__(self) -> None:
        validate_fields(self, "params")

    def gate(self, depth: np.ndarray | float) -> np.ndarray:
        """``gate(d) = max(d_thr, gate_sigmas · (sigma_base + sigma_quad · d²))`` (m) at measured depth ``d``."""
        return np.maximum(self.d_thr, self.gate_sigmas * (self.sigma_base + self.sigma_quad * np.square(depth)))

    @property
    def gate_coefficients(self) -> tuple[float, float, float]:
        """``(floor, a, b)`` with ``gate(d) = max(floor, a + b · d²)``, for the compiled kernels."""
        return (float(self.d_thr), float(self.gate_sigmas * self.sigma_base), float(self.gate_sigmas * self.sigma_quad))

    @property
    def cos_thr(self) -> float:
        """The angle filter as a cosine: a pair needs ``n_p · n_q > cos_thr``."""
        return float(np.cos(np.deg2rad(self.angle_deg)))

    @abstractmethod
    def associate(self, points: np.ndarray, normals: np.ndarray, frame: DepthFrame,
                  R: np.ndarray, t: np.ndarray) -> Pairs:
        """Pairs of source points (world) and pixels of ``frame`` seen from the guess (R, t).

        Inside ICP the arrays handed here are read-only copies, valid during this call only: the
        next call writes over them, so a method that keeps a frame or points copies what it keeps.
        The frame's truth (``true_points``, ``geom``, ``R``, ``t``) is withheld (NaN, ``NO_GEOM``)."""


def checked_inputs(points, normals, frame, R, t) -> tuple[np.ndarray, ...]:
    """C-contiguous float64 copies (views where already so) of the inputs, with one-line
    ``UserError``s for wrong shapes: points, normals (n, 3), R (3, 3), t (3,), frame maps (H, W, 3)."""
    if not isinstance(frame, DepthFrame):
        raise UserError(f"the target must be a DepthFrame, got {type(frame).__name__}")
    p = np.ascontiguousarray(points, dtype=np.float64)
    n = np.ascontiguousarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or n.shape != p.shape:
        raise UserError(f"source points and normals must both be (n, 3) arrays, got {p.shape} and {n.shape}")
    R = np.ascontiguousarray(R, dtype=np.float64)
    t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
    if R.shape != (3, 3) or t.shape != (3,):
        raise UserError(f"the pose guess must be R (3, 3) and t (3,), got {R.shape} and {t.shape}")
    h, w = frame.depth.shape
    if frame.vertices.shape != (h, w, 3) or frame.normals.shape != (h, w, 3):
        raise UserError(f"frame vertices and normals must be (H, W, 3) = ({h}, {w}, 3), "
                        f"got {frame.vertices.shape} and {frame.normals.shape}")
    return p, n, R, t


def checked_pairs(pairs: object, n_source: int, valid: np.ndarray) -> Pairs:
    """The ``Pairs`` a method returned, or a ``ValueError`` saying what is wrong (the frame then
    fails, as a feature method's invalid association does): ``source`` and ``pixel`` equal-length
    1-D integer arrays, ``0 ≤ source < n_source`` strictly ascending, ``0 ≤ pixel < H·W`` on a
    pixel where ``valid`` (the frame's ``valid``, flat) holds, ``len ≤ considered ≤ n_source``.
    The compiled kernels index with them unchecked, so an index out of range would read outside
    the frame (a crash, or garbage taken as a pose), and an invalid pixel's NaN vertex made the
    normal equations NaN (the frame failed as ``LinAlgError: Eigenvalues did not converge``)."""
    if not isinstance(pairs, Pairs):
        raise ValueError(f"a dense associator must return Pairs, got {type(pairs).__name__}")
    src, pix = np.asarray(pairs.source), np.asarray(pairs.pixel)
    for name, a in (("source", src), ("pixel", pix)):
        if a.ndim != 1 or not (np.issubdtype(a.dtype, np.integer) or a.size == 0):
            raise ValueError(f"Pairs.{name} must be a 1-D integer array, got {a.dtype} of shape {a.shape}")
    if len(src) != len(pix):
        raise ValueError(f"Pairs.source and Pairs.pixel differ in length ({len(src)} and {len(pix)})")
    src, pix = src.astype(np.int64, copy=False), pix.astype(np.int64, copy=False)
    if not _source_ascending(src, n_source):
        raise ValueError(f"Pairs.source must be strictly ascending indices in 0..{n_source - 1}")
    valid = np.ascontiguousarray(valid, dtype=np.bool_).reshape(-1)
    bad = _pixel_unusable(pix, valid)
    if bad >= 0 and not 0 <= pix[bad] < len(valid):
        raise ValueError(f"Pairs.pixel holds {pix[bad]}, outside the frame's pixels 0..{len(valid) - 1}")
    if bad >= 0:
        raise ValueError(f"Pairs.pixel holds {pix[bad]}, a pixel without a valid vertex and normal "
                         f"(frame.valid is False there): pair only valid pixels")
    considered = pairs.considered
    if not isinstance(considered, (int, np.integer)) or not len(src) <= considered <= n_source:
        raise ValueError(f"Pairs.considered must be an integer in {len(src)}..{n_source}, got {considered!r}")
    return Pairs(src, pix, int(considered))


@njit(cache=True)
def _source_ascending(src, n_source):
    """``0 ≤ src[0] < src[1] < … < n_source`` (one compiled pass: ICP checks every association)."""
    previous = -1
    for i in src:
        if i <= previous:
            return False
        previous = i
    return previous < n_source


@njit(cache=True)
def _pixel_unusable(pix, valid):
    """Index of the first entry of ``pix`` outside ``0..len(valid) − 1`` or where ``valid`` is
    False, or −1."""
    for k in range(len(pix)):
        if pix[k] < 0 or pix[k] >= len(valid) or not valid[pix[k]]:
            return k
    return -1


def flat_maps(frame: DepthFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frame's depth (H·W,), vertices and normals (H·W, 3) as C-contiguous float64, indexed
    by flat pixel ``v·W + u`` (views, no copy, for the maps ``vertex_map``/``normal_map`` make)."""
    h, w = frame.depth.shape
    return (np.ascontiguousarray(frame.depth, dtype=np.float64).reshape(h * w),
            np.ascontiguousarray(frame.vertices, dtype=np.float64).reshape(h * w, 3),
            np.ascontiguousarray(frame.normals, dtype=np.float64).reshape(h * w, 3))


def world_filters(points: np.ndarray, normals: np.ndarray, V: np.ndarray, N: np.ndarray, source: np.ndarray,
                  pixel: np.ndarray, R: np.ndarray, t: np.ndarray, gate: np.ndarray, cos_thr: float) -> np.ndarray:
    """Mask of candidate pairs passing ``|p − (R V + t)|² < gate²`` (``gate`` per pair or one
    value) and ``n_p · (R N) > cos_thr`` (NaN fails both)."""
    e = points[source] - (V[pixel] @ R.T + t)
    dot = np.einsum("ij,ij->i", normals[source], N[pixel] @ R.T)
    with np.errstate(invalid="ignore"):
        return (np.einsum("ij,ij->i", e, e) < np.square(gate)) & (dot > cos_thr)
