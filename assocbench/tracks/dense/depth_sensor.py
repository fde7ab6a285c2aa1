"""A depth sensor: turn a rendered (noise-free) z-depth image into the frame a dense method sees.

``depth_frame`` keeps every ``s``-th pixel, computes the truth (the world point each pixel sees,
from the noise-free depth and the true pose), then degrades the measurement the way structured-
light sensors do (Kinect-like, Nguyen et al. 2012): axial Gaussian noise whose sigma grows with
depth squared, dropouts where the view ray grazes the surface, optional random dropouts, and a
working range. Vertex and normal maps are built from the NOISY depth (``depth_frame.vertex_map``,
``normal_map``), as a real pipeline must. Missing is NaN everywhere, never 0.
"""

from __future__ import annotations

import numpy as np

from ...errors import UserError
from ...models.camera import Intrinsics
from ...models.depth_frame import DepthFrame, pixel_rays
from .depth_smoothing import edge_aware_smoothed
from .sensor_passes import edge_free_normals, grazing_kernel, sense
from .settings import DepthConfig


def downsample_intrinsics(K: Intrinsics, s: int) -> Intrinsics:
    """``K' = (W//s, H//s, f/s, cx/s, cy/s)``: pixel ``(i, j)`` of the strided image is pixel
    ``(s·i, s·j)`` of the full one, and ``(j − cx/s)/(f/s) = (s·j − cx)/f``: the same ray."""
    return Intrinsics(K.width // s, K.height // s, K.f / s, K.cx / s, K.cy / s)


def grazing_cosine(vertices: np.ndarray) -> np.ndarray:
    """``|n · V| / |V|`` (H, W): the cosine of the angle between the view ray and the surface
    normal (1 head-on, 0 grazing), with ``n ∝ (V[v+1, u] − V[v, u]) × (V[v, u+1] − V[v, u])`` as
    in ``depth_frame.normal_map``; the last row and column, which have no neighbour below or
    right, take the normal of the row above or the column left of them. NaN where a vertex
    involved is missing or the cross product vanishes.

    Computed as ``|c · V| / sqrt(|c|² |V|²)`` with the cross product ``c`` written out per
    component (``sensor_passes.view_cosine``), in one compiled pass (the numpy expression it
    replaced, term for term: the same values bit for bit, 0.5 ms against 3.2 ms a 320x240 frame).
    ``depth_frame`` computes the same cosine inside its own pass, from the noise-free depth."""
    return grazing_kernel(np.ascontiguousarray(vertices, dtype=np.float64))


def depth_frame(depth_true: np.ndarray, seg_geom: np.ndarray, R: np.ndarray, t: np.ndarray, K_full: Intrinsics,
                cfg: DepthConfig, rng: np.random.Generator) -> DepthFrame:
    """The frame the sensor measures at pose ``(R, t)`` (camera-to-world) from the rendered
    noise-free z-depth ``depth_true`` (H, W; NaN where nothing is hit) and segmentation
    ``seg_geom`` (H, W; geom id, ``NO_GEOM`` for background) at full resolution ``K_full``.

    Steps: stride by ``s``; truth ``X = R · V_true + t`` (NaN where nothing is hit, kept where
    the measurement later drops out); ``z = z_true + sigma(z_true) · N(0, 1)`` drawn for every
    pixel (so the noise at a pixel does not depend on which others are missing); drop pixels
    whose noise-free normal is more than ``grazing_deg`` from the view ray (this also drops the
    near side of depth edges, whose neighbour-difference normal spans the jump), a random
    ``dropout`` share, and measured depths outside ``[min_depth, max_depth]``; vertex and normal
    maps from the noisy depth. ``rng`` is the caller's, ``default_rng([seed, k, 17])`` for frame k:
    ``standard_normal`` for the whole frame, then (when ``dropout`` > 0) ``random`` for the dropouts.
    All but the draws is two compiled passes over the pixels (``sensor_passes``), around the smoothing.
    """
    depth_true, seg_geom = np.asarray(depth_true), np.asarray(seg_geom)
    expected = (K_full.height, K_full.width)
    if depth_true.shape != expected or seg_geom.shape != expected:
        raise UserError(f"depth {depth_true.shape} and segmentation {seg_geom.shape} must both be "
                        f"{expected} (height, width of the intrinsics)")
    s = cfg.downsample
    K = downsample_intrinsics(K_full, s)
    return sensed_frame(depth_true[::s, ::s][:K.height, :K.width], seg_geom[::s, ::s][:K.height, :K.width], R, t,
                        K, cfg, rng)


def _frame_block(h: int, w: int) -> dict[str, np.ndarray]:
    """The arrays of one frame (kept: vertices … geom; scratch of the passes: noise … dropout) as
    C-contiguous views of one buffer of 17·h·w float64 (10 MB at 320x240, which numpy advises onto
    huge pages): one allocation instead of a dozen, whose fresh 4 kB pages each cost a fault when
    first written (measured in a loop of frames on a loaded core: about 3 000 faults a frame before,
    1 900 with the passes writing separate arrays, 0-16 with the one buffer; 1-2 ms of the frame)."""
    shapes = {"vertices": (h, w, 3), "normals": (h, w, 3), "true_points": (h, w, 3), "depth": (h, w), "geom": (h, w),
              "noise": (h, w), "gate": (h, w), "smoothing": (3, h, w), "dropout": (h, w)}
    buf, at, out = np.empty(sum(int(np.prod(shape)) for shape in shapes.values())), 0, {}
    for name, shape in shapes.items():
        size = int(np.prod(shape))
        out[name] = buf[at:at + size].reshape(shape)
        at += size
    out["geom"] = out["geom"].view(np.int64)   # the same 8 bytes a pixel, read as the geom id
    return out


def sensed_frame(d_true: np.ndarray, seg: np.ndarray, R: np.ndarray, t: np.ndarray, K: Intrinsics, cfg: DepthConfig,
                 rng: np.random.Generator) -> DepthFrame:
    """``depth_frame`` of an already strided (H, W) noise-free depth and segmentation at the intrinsics
    ``K`` of the strided image (``cfg.downsample`` is not used): the draws, then the passes."""
    h, w = K.height, K.width
    R, t = np.array(R, dtype=np.float64), np.array(t, dtype=np.float64)
    if np.shape(d_true) != (h, w) or np.shape(seg) != (h, w) or R.shape != (3, 3) or t.shape != (3,):
        raise ValueError(f"sensed_frame: depth {np.shape(d_true)} and segmentation {np.shape(seg)} must be ({h}, {w}) "
                         f"(the intrinsics), R {R.shape} (3, 3) and t {t.shape} (3,)")   # the passes do not check
    a = _frame_block(h, w)
    rng.standard_normal(out=a["noise"])
    if cfg.dropout > 0:
        rng.random(out=a["dropout"])
    xu, yv = pixel_rays(K, h, w)
    params = (float(cfg.sigma_base), float(cfg.sigma_quad), float(np.cos(np.deg2rad(cfg.grazing_deg))),
              float(cfg.dropout), float(cfg.min_depth), float(cfg.max_depth))
    sense(np.ascontiguousarray(d_true, dtype=np.float64), np.ascontiguousarray(seg, dtype=np.int64), xu, yv, R, t,
          a["noise"], a["dropout"], params, a["depth"], a["vertices"], a["true_points"], a["geom"], a["gate"])
    _normals_into(a["depth"], a["gate"], K, cfg.normal_smooth_px, a["smoothing"], a["normals"])
    return DepthFrame(K, a["depth"], a["vertices"], a["normals"], a["true_points"], a["geom"], R, t)


def _normals_into(depth: np.ndarray, gate: np.ndarray, K: Intrinsics, smooth_px: float, work: np.ndarray,
                  out: np.ndarray) -> None:
    """The normal map of measured ``depth`` into ``out``: ``normal_map`` of the edge-aware smoothed
    depth (``depth_smoothing``, working in ``work`` (3, H, W); the raw depth when ``smooth_px`` is 0),
    NaN where the depth is missing and where a neighbour lies across a depth edge (``depth_edges``),
    in one compiled pass (``sensor_passes.edge_free_normals``)."""
    smooth = edge_aware_smoothed(depth, smooth_px, gate, work) if smooth_px > 0 else depth
    edge_free_normals(depth, smooth, gate, *pixel_rays(K, *depth.shape), out)
