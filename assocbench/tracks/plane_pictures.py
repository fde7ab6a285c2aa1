"""What ``assocbench frame`` and ``render`` draw on the lidar tracks: a top view per frame
(``viz.plane_view``); each track says what its map and features look like."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from ..belief.planar import open_loop_pose
from ..errors import UserError
from ..scoring.decisions import feature_decisions
from .base import loop_words
from .capabilities import RunFrame
from .plane_view import PlaneFrame, plane_bounds, plane_view, to_world


def scan_sequence(track, spec) -> Any:
    """The run's sequence with each frame's scan kept (``keep_scans``; its own cache entry)."""
    return track.lidar_source(replace(spec.source.spec, keep_scans=True)).sequence


def scan_points(seq, k: int) -> np.ndarray:
    """Frame ``k``'s scan hit points (p, 2) in the robot frame (none in the geometric mode)."""
    s = seq.scans[k] if seq.scans is not None else None
    return s.points() if s is not None else np.zeros((0, 2))


def real_features(seq, k: int, m: int) -> np.ndarray:
    """(m,) whether each feature images a landmark: the sensor's labels, then ``False`` for the
    belief's clutter."""
    labels = np.asarray(seq.labels[k], np.int64)
    return np.concatenate([labels >= 0, np.zeros(m - len(labels), bool)])


def _shapes(track, seq, k: int, z: np.ndarray, pose: np.ndarray) -> dict:
    """The features' shapes (``points`` or ``segments``) in the world, placed by ``pose``."""
    shapes = track.feature_shapes(seq, k, z)
    if "points" in shapes:
        return {"points": to_world(pose, shapes["points"])}
    segs = np.asarray(shapes["segments"], float).reshape(-1, 2, 2)
    return {"segments": to_world(pose, segs.reshape(-1, 2)).reshape(-1, 2, 2)}


def view_box(track, seq, the_map: dict) -> tuple[float, float, float, float]:
    """The box a whole run is drawn in: map, path and every detection at the true pose."""
    seen = [next(iter(_shapes(track, seq, k, seq.z[k], seq.poses[k]).values())).reshape(-1, 2)
            for k in range(len(seq))]
    return plane_bounds(seq.poses[:, :2], *the_map.values(), *seen)


def frame_picture(track, spec, index: int) -> tuple[np.ndarray, str]:
    """Frame ``index`` as the lidar saw it at the true pose: the scan, features marked real or
    spurious, and landmarks it missed."""
    seq_spec = spec.source.spec
    if not 0 <= index < seq_spec.frames:
        raise UserError(f"--index {index} is outside the trajectory's 0..{seq_spec.frames - 1}; "
                        f"raise --frames or lower it")
    seq = scan_sequence(track, spec)   # the whole path: a path's poses depend on its number of frames
    k, pose = index, seq.poses[index]
    labels = np.asarray(seq.labels[k], np.int64)
    status = ["landmark" if lab >= 0 else "spurious" for lab in labels]
    unseen = np.setdiff1d(np.flatnonzero(seq.visible[k]), labels[labels >= 0])
    the_map = track.picture_map(seq)
    title = (f"{seq.scene} {seq_spec.resolved_trajectory()} frame {k}: what the {track.name} track's lidar "
             f"saw (its truth)")
    view = PlaneFrame(title, view_box(track, seq, the_map), seq.poses[:k + 1, :2], pose,
                      to_world(pose, scan_points(seq, k)), status=status, kinds=("landmark", "spurious"),
                      **the_map, **_shapes(track, seq, k, seq.z[k], pose), **track.unseen(seq, unseen))
    line = (f"{title}: {len(labels)} features, {status.count('landmark')} of a landmark, "
            f"{status.count('spurious')} of none; {len(unseen)} landmarks detectable but not detected")
    return plane_view(view), line


def _caption(track, spec, rf: RunFrame, frames: int) -> str:
    head = f"{spec.source.name} | {spec.method} | frame {rf.k} of {frames} | {loop_words(spec)}"
    if rf.error:
        return f"{head}\nFAILED: {rf.error[:90]}"
    r = rf.record
    text = f"{r['tp']} right, {r['fp']} wrong, {r['fn']} missed pairings"
    if rf.estimator is not None:
        text += f"; pose error {100 * r['pos_err']:.1f} cm, {r['rot_err_deg']:.2f} deg"
    return f"{head}\n{text}"


def run_pictures(track, spec, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
    """One top view per recorded frame: features coloured by the method's decision
    (``feature_decisions``) at the estimated pose, on one box for the whole video."""
    seq = scan_sequence(track, spec)
    the_map = track.picture_map(seq)
    bounds = view_box(track, seq, the_map)
    est_path: list[np.ndarray] = []
    for rf in frames:
        k = rf.k
        if rf.estimator is None:
            pose = open_loop_pose(seq.poses[k], spec.belief, spec.seed, k)
        else:
            pose = np.asarray(rf.estimator.pose, float)
        est_path.append(pose[:2])
        p = rf.problem
        status = feature_decisions(p.landmark_ids, rf.truth.feature_labels, rf.association, real_features(seq, k, p.m))
        est_map, confirmed = (track.estimated_map(rf.estimator) if rf.estimator is not None
                              else (np.zeros((0, 2)), np.zeros(0, bool)))
        view = PlaneFrame(_caption(track, spec, rf, len(seq)), bounds, seq.poses[:k + 1, :2], seq.poses[k],
                          to_world(pose, scan_points(seq, k)), est_path=np.array(est_path), est_pose=pose,
                          est_joined=rf.estimator is not None, est_map=est_map, est_confirmed=confirmed,
                          status=status,
                          note=track.picture_note(), **the_map, **_shapes(track, seq, k, p.z, pose))
        yield plane_view(view)
