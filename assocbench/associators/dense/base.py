"""The dense associator interface: pair source points (world ``points`` and unit ``normals``, (n,
3)) with pixels of a ``DepthFrame`` seen from a guess ``(R, t)`` (camera-to-world). With
``q = R V[pixel] + t`` and ``n_q = R N[pixel]`` a pair passes the homework's filters

    target pixel valid (finite depth and normal),  |p_i − q| < gate(d),  n_p · n_q > cos(angle_deg)

(NaN fails all); the method finds the pixel (``projective``: the projection; ``kdtree``: the nearest
vertex). The gate grows with the depth noise at the pixel's depth ``d``:

    gate(d) = max(d_thr, gate_sigmas · σ(d)),   σ(d) = sigma_base + sigma_quad · d²

(the floor covers the guess's error, ``gate_sigmas · σ`` far pixels' scatter; 0 sigmas: fixed).
**Visible** points are the ``considered`` ones: in front, in the image, not hidden
(``z ≤ d + gate(d)``); a point seen through (in front of the surface by more than the gate) counts,
unpaired.
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
    """An association: ``source`` (k,) int64 indices into the source points, ascending, each at most
    once; ``pixel`` (k,) int64 flat pixels ``v·W + u``; ``considered`` the visible source points the
    method's first filter passed (``len / considered``: the share kept)."""

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
    """Base class. ``d_thr`` (m, > 0): the floor of the distance gate ``|p − q| < gate(d)``;
    ``gate_sigmas`` (≥ 0), ``sigma_base`` (m), ``sigma_quad`` (1/m): its growth with the depth
    noise; ``angle_deg`` (in (0, 180]): largest angle between a pair's normals. A bad value is a
    one-line ``UserError`` naming ``params.<field>``."""

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
        """Pairs of source points (world) and pixels of ``frame`` seen from the guess (R, t). Inside
        ICP the arrays are read-only copies valid during this call only (copy what you keep); the
        frame's truth is withheld (NaN, ``NO_GEOM``)."""


def checked_inputs(points, normals, frame, R, t) -> tuple[np.ndarray, ...]:
    """C-contiguous float64 copies (views where already so) of the inputs; wrong shapes are one-line
    ``UserError``s."""
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
    fails): equal-length 1-D integer arrays, ``0 ≤ source < n_source`` strictly ascending,
    ``0 ≤ pixel < H·W`` on a valid pixel, ``len ≤ considered ≤ n_source``. The compiled kernels
    index with them unchecked, and an invalid pixel's NaN vertex would make the normal equations
    NaN."""
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
    """First entry of ``pix`` outside ``valid``'s range or where ``valid`` is False, or −1."""
    for k in range(len(pix)):
        if pix[k] < 0 or pix[k] >= len(valid) or not valid[pix[k]]:
            return k
    return -1


def flat_maps(frame: DepthFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frame's depth (H·W,), vertices and normals (H·W, 3) as C-contiguous float64 views, by
    flat pixel."""
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
