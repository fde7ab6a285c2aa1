"""A depth sensor: a rendered noise-free z-depth image turned into the frame a dense method sees.

``depth_frame`` keeps every ``s``-th pixel, computes the truth, then degrades the depth as a
structured-light sensor does (Nguyen et al. 2012): axial noise growing with depth², dropouts at
grazing view, random dropouts, a working range. Vertices and normals come from the NOISY depth.
Missing is NaN, never 0.
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
    """``|n · V| / |V|`` (H, W): cosine between view ray and normal
    ``n ∝ (V[v+1, u] − V[v, u]) × (V[v, u+1] − V[v, u])`` (last row and column take their
    neighbour's); NaN where undefined. One compiled pass, bit for bit the numpy expression."""
    return grazing_kernel(np.ascontiguousarray(vertices, dtype=np.float64))


def depth_frame(depth_true: np.ndarray, seg_geom: np.ndarray, R: np.ndarray, t: np.ndarray, K_full: Intrinsics,
                cfg: DepthConfig, rng: np.random.Generator) -> DepthFrame:
    """The frame measured at ``(R, t)`` from noise-free ``depth_true`` and ``seg_geom`` (H, W) at
    ``K_full``: stride by ``s``; truth ``X = R · V_true + t``;
    ``z = z_true + sigma(z_true) · N(0, 1)`` drawn for every pixel (a pixel's noise does not depend
    on which others drop); drop grazing pixels (beyond ``grazing_deg``: also a depth edge's near
    side), a random ``dropout`` share and depths outside ``[min_depth, max_depth]``; vertices and
    normals from the noisy depth. ``rng``: ``default_rng([seed, k, 17])``, ``standard_normal`` for
    the frame then ``random`` for the dropouts.
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
    """The frame's arrays as views of one 17·h·w float64 buffer: one allocation, its pages faulted
    once (``benchmarks/dense_depth_frame.py``)."""
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
    """Normals of the edge-aware smoothed ``depth`` into ``out`` (raw when ``smooth_px`` is 0), NaN
    where missing or across a depth edge."""
    smooth = edge_aware_smoothed(depth, smooth_px, gate, work) if smooth_px > 0 else depth
    edge_free_normals(depth, smooth, gate, *pixel_rays(K, *depth.shape), out)
