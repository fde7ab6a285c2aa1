"""One run of the dense track: depth frames tracked by point-to-plane ICP and fused into a map,
inside the harness's worker.

Frame 0 seeds the map at its true pose; then per frame: (1) the source is the fused map
(``dense.tracking: model``), the previous frame's points (``frame``) or the map fused at true poses
(``truth``: one step's error without drift), entering as the model rendered into the view or as
every map point (``dense.prediction``); (2) ICP pairs source points with pixels (the method's call:
timed, killed past ``time_limit_s``, its exception recorded; a failure holds the pose and the frame
is not fused); (3) the frame is fused at the estimate. Each frame is scored (correspondences,
relative pose error, time); the last record carries the map's error, compression and a picture
subsample. A resumed worker replays frames ``< first`` without sending them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...models.depth_frame import DepthFrame
from ...scoring.trajectory import pose_columns
from ...sim.scene import load_scene
from ..capabilities import MethodCalls
from .fusion import PointMap, compression_ratio, fuse
from .icp import IcpConfig, icp
from .metrics import relative_pose_error, score_associations
from .picture_json import fixed_json
from .prediction import Splatter, gather_rows
from .sequence import DenseSequence
from .summary import METHOD_FAILED
from .surface import surface_distance

PICTURE_POINTS = 10_000   # map points kept in the last record for the leaderboard's top view


@dataclass
class Source:
    """Points ICP registers to the new frame, in world coordinates, with their truth."""

    points: np.ndarray
    normals: np.ndarray
    true_points: np.ndarray
    geom: np.ndarray
    visited: int = 0   # map points the prediction visited to find them (0: no prediction)


def frame_source(frame: DepthFrame, R: np.ndarray, t: np.ndarray) -> Source:
    """A frame's measured points and normals placed at pose ``(R, t)`` (frame-to-frame tracking)."""
    ok = frame.valid.reshape(-1)
    return Source(frame.vertices.reshape(-1, 3)[ok] @ R.T + t, frame.normals.reshape(-1, 3)[ok] @ R.T,
                  frame.true_points.reshape(-1, 3)[ok], frame.geom.reshape(-1)[ok])


def map_source(pmap: PointMap) -> Source:
    """Every map point (``dense.prediction: map``: the homework's projection of the whole map,
    O(map) in every ICP iteration)."""
    return Source(pmap.positions, pmap.normals, pmap.true_points, pmap.geom)


def view_source(pmap: PointMap, splatter: Splatter, R: np.ndarray, t: np.ndarray, index: bool = True) -> Source:
    """The map points visible from ``(R, t)``, one per pixel (``prediction``); ``index``: visit only
    blocks in view."""
    rows, scanned = splatter.shown_rows(pmap, R, t, index)
    return Source(*gather_rows(rows, pmap.positions, pmap.normals, pmap.true_points, pmap.geom), scanned)


def model_source(pmap: PointMap, splatter: Splatter, R: np.ndarray, t: np.ndarray, dense) -> Source:
    """The source of frame-to-model tracking from the predicted pose ``(R, t)`` (``dense``: the
    run's ``DenseConfig``)."""
    return view_source(pmap, splatter, R, t, dense.index) if dense.prediction == "view" else map_source(pmap)


def unmeasurable(seq: DenseSequence, first: DepthFrame) -> str:
    """Why the run cannot be measured at all ("" if it can): no measured pixel in the first frame.
    Not ok."""
    if first.valid.any():
        return ""
    reason = "every pixel is beyond depth.max_depth or missing" if np.isfinite(seq.depths[0]).any() \
        else "the camera sees nothing"
    return (f"the first depth frame of {seq.scene!r} has no valid pixel ({reason}); it seeds the map: check "
            "depth.min_depth/max_depth/dropout and the scene's path")


def unmeasured_records(seq: DenseSequence, first: int, error: str) -> Iterator[dict]:
    """Records of a run that could not start: every frame failed with ``error``, poses held."""
    for k in range(first, len(seq)):
        yield {"frame": k, "icp_converged": False, "icp_failed": True, "icp_reason": "not measured", "error": error,
               "map_points": 0, **pose_columns("true_", seq.rotations[k], seq.positions[k]),
               **pose_columns("est_", seq.rotations[0], seq.positions[0])}


def fusion_columns(stats) -> dict:
    """A fused frame's fusion columns of its record (``fuse``'s stats); a frame not fused has none."""
    return {"merged": stats.merged, "added": stats.added, "removed": stats.removed, "fusion_visited": stats.scanned,
            "fusion_considered": stats.considered}


def dense_records(seq: DenseSequence, spec, calls: MethodCalls, build, first: int = 0,
                  artifacts: Path | None = None) -> Iterator[dict]:
    """Per-frame records of ``spec`` (a ``RunSpec`` of the dense track) from frame ``first`` on.
    ``build()`` makes the run's associator (through ``calls``: its failure fails every frame)."""
    cfg, fusion, dense = spec.settings.icp, spec.settings.fusion, spec.settings.dense
    frame = seq.frame(0)
    error = unmeasurable(seq, frame)
    if error:
        yield from unmeasured_records(seq, first, error)
        return
    associator, build_error = calls.build(build)
    pmap, splatter = PointMap(), Splatter(seq.K, fusion.d_thr)   # the band: fusion's same surface
    R_est, t_est = seq.rotations[0].copy(), seq.positions[0].copy()
    start = time.perf_counter()
    stats = fuse(pmap, frame, R_est, t_est, 0, fusion)
    # frame 0 is fused (into the empty map) as every tracked frame is: its fusion columns are filled
    # too, since an empty one reads as a frame not fused
    record = {"frame": 0, "icp_converged": True, "icp_failed": False, "icp_reason": "first frame (given pose)",
              "fusion_s": time.perf_counter() - start, **fusion_columns(stats), "map_points": len(pmap), "error": "",
              **pose_columns("true_", seq.rotations[0], seq.positions[0]), **pose_columns("est_", R_est, t_est)}
    previous = frame
    for k in range(1, len(seq)):
        if record["frame"] >= first:
            yield record
        start = time.perf_counter()
        frame = seq.frame(k)
        frame_s = time.perf_counter() - start
        R_prev, t_prev = (seq.rotations[k - 1], seq.positions[k - 1]) if dense.tracking == "truth" else (R_est, t_est)
        start = time.perf_counter()
        source = frame_source(previous, R_prev, t_prev) if dense.tracking == "frame" else \
            model_source(pmap, splatter, R_prev, t_prev, dense)
        predict_s = time.perf_counter() - start
        record, R_k, t_k = track_frame(k, seq, frame, source, associator, build_error, calls, R_prev, t_prev, cfg,
                                       dense.truth_tol)
        record |= {"frame_s": frame_s, "predict_s": predict_s, "predict_visited": source.visited}
        if not record["icp_failed"] or dense.tracking == "truth":
            R_fuse, t_fuse = (seq.rotations[k], seq.positions[k]) if dense.tracking == "truth" else (R_k, t_k)
            start = time.perf_counter()
            stats = fuse(pmap, frame, R_fuse, t_fuse, k, fusion, dense.index)
            record |= {"fusion_s": time.perf_counter() - start, **fusion_columns(stats)}
        record["map_points"] = len(pmap)
        if dense.tracking != "truth":
            R_est, t_est = R_k, t_k
        if not record["icp_failed"]:   # a lost frame's pose is unknown: the next registers to the last tracked one
            previous = frame
    yield record | run_end(seq, spec, pmap, artifacts)


def track_frame(k: int, seq: DenseSequence, frame: DepthFrame, source: Source, associator, build_error: str,
                calls: MethodCalls, R0: np.ndarray, t0: np.ndarray, cfg: IcpConfig,
                tol: float) -> tuple[dict, np.ndarray, np.ndarray]:
    """ICP of frame ``k`` from ``(R0, t0)`` as the method's call: its record and the pose to carry on."""
    def held(runtime: float, error: str) -> dict:   # built only when the call failed: pose columns are not free
        return {"frame": k, "icp_converged": False, "icp_failed": True, "source_points": len(source.points),
                **pose_columns("true_", seq.rotations[k], seq.positions[k]), **pose_columns("est_", R0, t0),
                "icp_reason": METHOD_FAILED, "icp_s": runtime, "error": error}

    if associator is None or k in calls.faults:
        error, runtime = calls.faults.get(k, (build_error, 0.0))
        return held(runtime, error), R0, t0
    res, elapsed, error = calls.call(k, lambda: icp(source.points, source.normals, frame, associator, R0, t0, cfg))
    if res is None:
        return held(elapsed, error), R0, t0
    R_k, t_k = (R0, t0) if res.failed else (res.R, res.t)
    start = time.perf_counter()
    first, last = score_associations(source.true_points, source.geom, frame, [
        (res.first_pairs.source, res.first_pairs.pixel), (res.pairs.source, res.pairs.pixel)], tol)
    rpe_t, rpe_r = relative_pose_error(seq.rotations[k - 1], seq.positions[k - 1], seq.rotations[k],
                                       seq.positions[k], R0, t0, R_k, t_k)
    rec = {"frame": k, "icp_converged": bool(res.converged), "icp_failed": bool(res.failed),
           "icp_reason": res.reason, "icp_iterations": int(res.iterations), "icp_s": elapsed,
           "associate_s": res.associate_s, "error": "",
           "source_points": len(source.points), "pairs_start": first.pairs, "pairs": last.pairs,
           "precision_start": first.precision, "recall_start": first.recall,
           "precision": last.precision, "recall": last.recall, "partners": last.partners,
           "inlier_share": float(res.inlier_share), "direction_share": float(res.direction_share),
           "icp_rms_mm": 1000 * float(res.rms),
           "step_error_mm": 1000 * rpe_t, "step_error_deg": rpe_r, "score_s": time.perf_counter() - start,
           **pose_columns("true_", seq.rotations[k], seq.positions[k]), **pose_columns("est_", R_k, t_k)}
    return rec, R_k, t_k


def run_end(seq: DenseSequence, spec, pmap: PointMap, artifacts: Path | None) -> dict:
    """The last record's map error (mm), compression and picture subsample (``born`` order, so row
    order changes nothing); the map to ``artifacts/map.npz`` when asked."""
    error = surface_distance(pmap.positions, load_scene(spec.source.spec.scene)) if len(pmap) else np.zeros(0)
    birth = np.argsort(pmap.born)   # after the distance, which runs faster over spatially sorted rows
    positions, error_mm = pmap.positions[birth], 1000 * error[birth]
    if artifacts is not None:
        np.savez(Path(artifacts) / "map.npz", positions=positions, normals=pmap.normals[birth],
                 weights=pmap.weights[birth], error_mm=error_mm)
    step = max(1, len(pmap) // PICTURE_POINTS)
    picture = np.column_stack([positions[::step], error_mm[::step]]) if len(pmap) else np.zeros((0, 4))
    return {"map_median_mm": float(np.median(error_mm)) if len(error_mm) else float("nan"),
            "map_p95_mm": float(np.percentile(error_mm, 95)) if len(error_mm) else float("nan"),
            "compression_pct": 100 * compression_ratio(len(pmap), len(seq), seq.K.width, seq.K.height),
            "final_map": fixed_json(picture)}
