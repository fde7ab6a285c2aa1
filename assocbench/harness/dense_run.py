"""One run of the dense track: depth frames tracked by point-to-plane ICP and fused into a map.

Per frame k ≥ 1 (frame 0 seeds the map at its true pose, as the homework's first frame does):

1. the source is the fused map (``dense.tracking: model``, the homework's frame-to-model) or the
   previous frame's points placed at their estimated pose (``frame``); ``truth`` fuses at the true
   poses and runs ICP from the previous true pose, which isolates one step's error from drift;
2. ICP from the previous estimate pairs source points with pixels (the run's method: projective
   or kdtree) and solves for the pose; a failed ICP keeps the previous pose and the frame is not
   fused (a lost frame must not damage the map);
3. the frame is fused at the estimated pose.

Each frame is scored for its correspondences (first and last ICP iteration) against per-pixel
truth, its relative pose error, and its time; the run for drift (ATE), map size, compression
and the map's distance to the true surfaces.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..associators.dense.registry import make_dense_associator
from ..errors import UserError
from ..tracks.dense.icp import IcpConfig, icp
from ..tracks.dense.fusion import PointMap, compression_ratio, fuse
from ..tracks.dense.metrics import relative_pose_error, score_correspondences
from ..tracks.dense.surface import surface_distance
from ..tracks.dense.sequence import DenseSequence, load_dense_sequence
from ..models.depth_frame import DepthFrame
from ..sim.scene import load_scene
from ..tracks.dense.spec import DenseRunSpec


@dataclass
class Source:
    """Points ICP registers to the new frame, in world coordinates, with their truth."""

    points: np.ndarray
    normals: np.ndarray
    true_points: np.ndarray
    geom: np.ndarray


def frame_source(frame: DepthFrame, R: np.ndarray, t: np.ndarray) -> Source:
    """A frame's measured points and normals placed at pose ``(R, t)`` (frame-to-frame tracking)."""
    ok = frame.valid.reshape(-1)
    return Source(frame.vertices.reshape(-1, 3)[ok] @ R.T + t, frame.normals.reshape(-1, 3)[ok] @ R.T,
                  frame.true_points.reshape(-1, 3)[ok], frame.geom.reshape(-1)[ok])


def map_source(pmap: PointMap) -> Source:
    return Source(pmap.positions, pmap.normals, pmap.true_points, pmap.geom)


def check_first_frame(seq: DenseSequence, first: DepthFrame) -> None:
    """Refuse a sequence the track cannot start on: no measured pixel in the first frame (it seeds
    the map) is one line, not a run of NaN."""
    if not first.valid.any():
        reason = "every pixel is beyond depth.max_depth or missing" if np.isfinite(seq.depths[0]).any() \
            else "the camera sees nothing"
        raise UserError(f"the first depth frame of {seq.scene!r} has no valid pixel ({reason}); it seeds the map: "
                        "check depth.min_depth/max_depth/dropout and the scene's path")


def pose_columns(prefix: str, R: np.ndarray, t: np.ndarray) -> dict:
    q = Rotation.from_matrix(R).as_quat()
    return {f"{prefix}{c}": float(v) for c, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), (*t, *q))}


def run_dense(spec: DenseRunSpec, cache_dir=None) -> tuple[list[dict], dict]:
    """Per-frame records and end-of-run facts (map, its error, naive size) of ``spec``."""
    seq = load_dense_sequence(spec.sequence, cache_dir)
    frame = seq.frame(0)
    check_first_frame(seq, frame)
    associator = make_dense_associator(spec.method, **spec.params)
    tracking, tol = spec.dense.tracking, spec.dense.truth_tol
    pmap = PointMap()
    R_est, t_est = seq.rotations[0].copy(), seq.positions[0].copy()
    start = time.perf_counter()
    fuse(pmap, frame, R_est, t_est, 0, spec.fusion)
    records = [{"frame": 0, "icp_converged": True, "icp_failed": False, "icp_reason": "first frame (given pose)",
                "fusion_s": time.perf_counter() - start, "map_points": len(pmap),
                **pose_columns("true_", seq.rotations[0], seq.positions[0]), **pose_columns("est_", R_est, t_est)}]
    previous = frame
    for k in range(1, len(seq)):
        frame = seq.frame(k)
        R_prev, t_prev = (seq.rotations[k - 1], seq.positions[k - 1]) if tracking == "truth" else (R_est, t_est)
        source = frame_source(previous, R_prev, t_prev) if tracking == "frame" else map_source(pmap)
        rec, R_k, t_k = track_frame(k, seq, frame, source, associator, R_prev, t_prev, spec.icp, tol)
        R_fuse, t_fuse = (seq.rotations[k], seq.positions[k]) if tracking == "truth" else (R_k, t_k)
        if not rec["icp_failed"] or tracking == "truth":
            start = time.perf_counter()
            stats = fuse(pmap, frame, R_fuse, t_fuse, k, spec.fusion)
            rec |= {"fusion_s": time.perf_counter() - start, "merged": stats.merged, "added": stats.added,
                    "removed": stats.removed}
        rec["map_points"] = len(pmap)
        records.append(rec)
        if tracking != "truth":
            R_est, t_est = R_k, t_k
        previous = frame
    error = surface_distance(pmap.positions, load_scene(spec.sequence.scene)) if len(pmap) else np.zeros(0)
    end = {"map": pmap, "map_error": error,
           "compression": compression_ratio(len(pmap), len(seq), seq.K.width, seq.K.height)}
    return records, end


def track_frame(k: int, seq: DenseSequence, frame: DepthFrame, source: Source, associator, R0: np.ndarray,
                t0: np.ndarray, cfg: IcpConfig, tol: float) -> tuple[dict, np.ndarray, np.ndarray]:
    """ICP of frame ``k`` from ``(R0, t0)``: its record and the pose to carry on with."""
    start = time.perf_counter()
    # no try/except here: dense methods are built-ins only, so an exception is a bug to see, and a
    # Ctrl-C that lands inside a compiled kernel (numba re-raises it as SystemError) must end the run
    res = icp(source.points, source.normals, frame, associator, R0, t0, cfg)
    elapsed = time.perf_counter() - start
    R_k, t_k = (R0, t0) if res.failed else (res.R, res.t)
    first = score_correspondences(source.true_points, source.geom, frame, res.first_pairs.source,
                                  res.first_pairs.pixel, tol)
    last = score_correspondences(source.true_points, source.geom, frame, res.pairs.source, res.pairs.pixel, tol)
    rpe_t, rpe_r = relative_pose_error(seq.rotations[k - 1], seq.positions[k - 1], seq.rotations[k],
                                       seq.positions[k], R0, t0, R_k, t_k)
    rec = {"frame": k, "icp_converged": bool(res.converged), "icp_failed": bool(res.failed),
           "icp_reason": res.reason, "icp_iterations": int(res.iterations), "icp_s": elapsed,
           "source_points": len(source.points), "pairs_start": first.pairs, "pairs": last.pairs,
           "precision_start": first.precision, "recall_start": first.recall,
           "precision": last.precision, "recall": last.recall, "partners": last.partners,
           "inlier_share": float(res.inlier_share), "icp_rms_mm": 1000 * float(res.rms),
           "step_error_mm": 1000 * rpe_t, "step_error_deg": rpe_r,
           **pose_columns("true_", seq.rotations[k], seq.positions[k]), **pose_columns("est_", R_k, t_k)}
    return rec, R_k, t_k
