"""The dense track end to end and per stage, as the map grows: `assocbench run --method projective
--scene crates` at 320x240 on one core, frame-to-model tracking against the model rendered into the
view (``dense.prediction: view``) with the map's index (the splat and fusion visit only the blocks in
view), beside three baselines timed in the same process: the same without the index
(``dense.index=false``: the splat and fusion visit every map point; the same numbers bit for bit),
the homework's fusion (``fusion.voxel=0``: every pixel no map point merged with is added, so the
map's density in view grows with every new viewpoint; the default keeps one point per 1 cm cell)
and the projection of every map point in every ICP iteration (``dense.prediction=map``).

What it runs. ``assocbench run --method projective --scene crates --frames N`` with
``resolution=[320,240]``, ``depth.downsample=1`` and the scene's own path (the crates circle; the
bays line with ``--scene bays``) laid out so that the camera moves as far a frame as on the default
200-frame path whatever N (``turns = 0.07 · max(N, 200) / 200``; bays ``length = 4.5 m · max(N, 200)
/ 200``, which passes the last bays landmark at about 570 frames: a longer path is refused),
its sequence cached beforehand (rendering is not timed: a cached run is the case stated). The
command runs in this process (``cli.main.main``), after one untimed warm-up run, so the numbers
exclude Python's start and numba's compilation but include everything else the command does:
the harness, its worker, the depth frames (noise, smoothing, normals), prediction, ICP, fusion,
scoring, the map's distance to the true surfaces, and writing the run's files (``map.png``,
``map.ply``, CSV).

Columns. ``e2e fps``: N / the command's wall time (median of ``--runs``). The stages are the
per-frame records' medians (ms): ``depth frame`` (``DenseSequence.frame``: noise, smoothing,
vertex and normal maps), of which ``smoothing`` (the edge-aware Gaussian, timed here on the same
frames), ``prediction`` (the splat; 0 for ``map``), ``association`` (all of ICP's associator calls
in that frame), ``ICP`` (the whole call, association included), ``fusion``, ``scoring`` (the
correspondences against per-pixel truth, the pose errors). The last three columns compare the
first and the last tenth of the run (medians): the map's size, the source points ICP is handed,
and the association's time per ICP iteration (the iteration count falls as the path settles, so
per frame would mislead): a cost that follows the pixel count stays level while the map grows;
``visited`` (first -> last tenth) is the map points the splat and the fusion visited per frame
(the work the index bounds: counted, not timed).

A second table registers frame pairs (k, k+1) of the same sequence with ours, small_gicp and Open3D
(``registrations``), where installed (the ``bench`` extra; one line says when one is not).

Usage: python benchmarks/dense_rate.py [--frames 50 200 500] [--runs 3] [--baseline-frames 50 200 500]
       [--map-frames 50 200] [--pairs 8]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import tempfile
import time
import uuid
from pathlib import Path

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):   # one core: before numpy/numba/open3d read them
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402

from assocbench.cli.main import main as cli  # noqa: E402
from assocbench.errors import UserError  # noqa: E402
from assocbench.harness.config import load_run_config, run_spec  # noqa: E402
from assocbench.sim.scene import load_scene  # noqa: E402
from assocbench.sim.trajectory import rig_for  # noqa: E402
from assocbench.tracks.dense.depth_smoothing import depth_gate, edge_aware_smoothed  # noqa: E402
from assocbench.tracks.dense.sequence import DENSE_PATHS, PATH_FRAMES, DenseSequenceSpec, load_dense_sequence  # noqa: E402

STAGES = (("depth frame", "frame_s"), ("prediction", "predict_s"), ("association", "associate_s"),
          ("ICP", "icp_s"), ("fusion", "fusion_s"), ("scoring", "score_s"))


# the rows: label, the source's settings
SOURCES = (("view", ["dense.prediction=view"]), ("view, no index (baseline)", ["dense.prediction=view", "dense.index=false"]),
           ("view, homework fusion (baseline)", ["dense.prediction=view", "fusion.voxel=0"]),
           ("map (baseline)", ["dense.prediction=map"]))


def path_settings(scene: str, path: int) -> list[str]:
    """The scene's own dense path (``sequence.DENSE_PATHS``: the crates circle, the bays line) laid
    out over ``path`` frames at the default 200-frame path's speed a frame: its ``turns`` or
    ``length`` scaled by path / 200 (crates 0.07 turns, bays 4.5 m at 200 frames: 0.175 turns and
    11.25 m at 500). A scene without one keeps the run's own path."""
    if scene not in DENSE_PATHS:
        return []
    name, params = DENSE_PATHS[scene]
    scaled = [f"trajectory_params.{key}={value * path / PATH_FRAMES:.6g}" for key, value in params.items()
              if key in ("turns", "length")]
    return [f"trajectory={name}", *scaled]


def settings(scene: str, frames: int, source: list[str]) -> list[str]:
    """The command's ``--set`` options: 320x240, the scene's path at the default path's speed a
    frame (``path_settings``), the source's."""
    path = max(frames, PATH_FRAMES)
    sets = ["resolution=[320,240]", "depth.downsample=1", f"dense.path_frames={path}", f"limits.frames={max(path, 1000)}",
            *path_settings(scene, path), *source]
    return [a for s in sets for a in ("--set", s)]


def sequence_spec(scene: str, frames: int) -> DenseSequenceSpec:
    """The run's depth sequence, checked before anything renders: a bad ``--scene`` or a path that
    leaves the scene's landmarks (``check_inside``) is a ``UserError``."""
    sets = settings(scene, frames, [])[1::2]
    spec = run_spec(load_run_config(None, sets, method="projective", scene=scene, frames=frames)).source.spec
    check_inside(spec)
    return spec


def check_inside(spec: DenseSequenceSpec) -> None:
    """Refuse a stretched line (``path_settings``: bays and corridor) whose camera passes the scene's
    last landmark along the rig's axis: the bays line, 4.5 m a 200 frames from x = 1.42 m, passes the
    last bays landmark (x = 14.25 m) at about path frame 570 and reaches the end wall (15 m) near 604
    (at 700 frames it ends at x = 17.2 m, through the wall)."""
    if "length" not in DENSE_PATHS.get(spec.scene, ("", {}))[1]:
        return
    scene, cam = load_scene(spec.scene), spec.camera_path()
    rig = rig_for(scene.landmarks, scene.normals, scene.fovy, cam.width / cam.height, scene.free_distance)
    along, marks = cam.poses(scene)[1] @ rig.axis, scene.landmarks @ rig.axis
    past = np.flatnonzero((along < marks.min()) | (along > marks.max()))
    if len(past):
        raise UserError(f"--frames {cam.frames}: the {spec.scene} line at the default path's speed passes the "
                        f"scene's last landmark at path frame {past[0]} and would leave the scene; use --frames "
                        f"at most {past[0]}")


def render_once(scene: str, frames: int) -> object:
    """Load (rendering and caching when absent) the run's depth sequence, untimed."""
    return load_dense_sequence(sequence_spec(scene, frames))


def run(scene: str, frames: int, source: list[str], out: Path) -> tuple[float, pd.DataFrame]:
    """Wall time (s) of the command and its per-frame records."""
    argv = ["run", "--method", "projective", "--scene", scene, "--frames", str(frames), *settings(scene, frames, source),
            "--out", str(out), "--format", "csv"]
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = cli(argv)
    wall = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"`assocbench {' '.join(argv)}` exited {code}")
    return wall, pd.read_csv(out / "frames.csv")


def smoothing_ms(seq, frames: int) -> float:
    """Median time (ms) of the edge-aware smoothing on the run's own noisy frames."""
    cfg, times = seq.depth_cfg, []
    for k in range(0, frames, max(1, frames // 20)):
        depth = seq.frame(k).depth
        gate = depth_gate(depth, cfg.sigma(depth))
        start = time.perf_counter()
        edge_aware_smoothed(depth, cfg.normal_smooth_px, gate)
        times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def row(label: str, frames: int, walls: list[float], records: pd.DataFrame, smooth: float) -> list:
    """One table row: end-to-end fps, stage medians (ms), the stage total early and late in the run."""
    ms = {col: 1000 * float(records[col].dropna().median()) if col in records else 0.0 for _, col in STAGES}
    tenth = max(1, len(records) // 10)
    early, late = records.iloc[1:tenth + 1], records.iloc[-tenth:]
    per_iteration = lambda part: 1000 * float((part["associate_s"] / part["icp_iterations"].clip(lower=1)).median())  # noqa: E731
    kilo = lambda col: f"{early[col].median() / 1000:.0f}k -> {late[col].median() / 1000:.0f}k"  # noqa: E731
    visited = (lambda col: kilo(col) if records[col].notna().any() and records[col].max() > 0 else "-")  # noqa: E731
    return [label, frames, frames / float(np.median(walls)), 1000 * float(np.median(walls)) / frames,
            ms["frame_s"], smooth, ms["predict_s"], ms["associate_s"], ms["icp_s"], ms["fusion_s"], ms["score_s"],
            kilo("map_points"), kilo("source_points"), f"{per_iteration(early):.2f} -> {per_iteration(late):.2f}",
            visited("predict_visited"), visited("fusion_visited")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[50, 200, 500])
    ap.add_argument("--baseline-frames", type=int, nargs="*", default=[50, 200, 500],
                    help="run lengths at which the no-index and homework-fusion baselines are timed too")
    ap.add_argument("--map-frames", type=int, nargs="*", default=[50, 200],
                    help="run lengths at which the whole-map projection is timed too (it is the slow one)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scene", default="crates")
    ap.add_argument("--pairs", type=int, default=8, help="frame pairs of the registration table (0: none)")
    args = ap.parse_args()
    if min(args.frames) < 2:
        ap.error(f"--frames must be at least 2 (frame 1 is tracked from frame 0), got {min(args.frames)}")
    try:   # a bad --scene, or a path leaving it, in one line before anything is printed or rendered
        for n in args.frames:
            sequence_spec(args.scene, n)
    except UserError as exc:
        ap.error(str(exc))
    print(f"load average {load()} on {os.cpu_count()} cores (the machine is shared: timings are noisy)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.frames:
            seq = render_once(args.scene, n)
            smooth = smoothing_ms(seq, n)
            for label, source in sources(n, args.baseline_frames, args.map_frames):
                run(args.scene, min(n, 20), source, Path(tmp) / uuid.uuid4().hex)   # warm-up, untimed
                results = [run(args.scene, n, source, Path(tmp) / uuid.uuid4().hex) for _ in range(args.runs)]
                walls = [w for w, _ in results]
                rows.append(row(label, n, walls, results[0][1], smooth) + [load()])
    print_table(["source", "frames", "e2e fps", "e2e ms/frame", "depth frame", "smoothing", "prediction",
                 "association", "ICP", "fusion", "scoring", "map points", "ICP source points",
                 "association ms/iteration", "splat visited", "fusion visited", "load after"], rows)
    print("stage columns: median ms per frame; smoothing is part of the depth frame; association is part of ICP; "
          "early -> late: medians over the first and the last tenth of the run")
    registrations(render_once(args.scene, min(args.frames)), args.pairs, args.runs)


def sources(frames: int, baseline_frames: list[int], map_frames: list[int]) -> list:
    """The rows timed at ``frames``: the view, the view without index, the view with the homework's
    fusion (every unmerged pixel added), the whole-map projection."""
    return [SOURCES[0]] + [SOURCES[1], SOURCES[2]] * (frames in baseline_frames) + [SOURCES[3]] * (frames in map_frames)


def load() -> str:
    """The 1-minute load average and the number of cores, to print beside every figure."""
    return f"{os.getloadavg()[0]:.1f}/{os.cpu_count()}"


def registrations(seq, pairs: int, runs: int) -> None:
    """Ours beside small_gicp and Open3D per registration, on the same frame pairs (k, k+1) of the
    run's sequence, frame-to-frame from frame k's true pose, one thread: ours is ``icp`` with the
    projective associator and the run's defaults; small_gicp is ``align(..., "PLANE_ICP")`` on the
    same points (target in frame k+1's camera, source in world coordinates, so its
    ``T_target_source`` is frame k+1's world-to-camera pose), with its own normals, no downsampling
    below 5 mm, the same 5 cm correspondence distance, our convergence thresholds (5e-3 deg, 0.1 mm)
    and our 100 iterations at most; Open3D is ``registration_icp`` point-to-plane on the same points
    with our target normals (its k-d tree association), the same 5 cm distance, relative fitness
    and rmse 1e-6 and 100 iterations at most (``benchmarks/dense_vs_open3d.py`` compares the two
    at length). Errors: the estimated camera's distance (mm) and angle (deg) to frame k+1's true
    pose; time: median of ``runs`` calls (ms). ``pairs`` 0: no table."""
    if pairs <= 0:
        return
    from assocbench.associators.registry import make_dense_associator
    from assocbench.tracks.dense.icp import icp, step_from
    from assocbench.tracks.dense.run import frame_source
    from assocbench.tracks.dense.settings import IcpConfig

    small_gicp, o3d = optional("small_gicp"), optional("open3d")
    if o3d is not None and hasattr(o3d.utility, "set_max_threads"):
        o3d.utility.set_max_threads(1)
    rows, cfg = [], IcpConfig()
    for k in np.linspace(0, len(seq) - 2, pairs).astype(int):
        A, B = seq.frame(k), seq.frame(k + 1)
        src = frame_source(A, A.R, A.t)
        assoc = make_dense_associator("projective")
        res, t_ours = timed_median(lambda: icp(src.points, src.normals, B, assoc, A.R, A.t, cfg), runs)
        row = [int(k), 1000 * step_from(B.R, B.t, res.R, res.t)[0], step_from(B.R, B.t, res.R, res.t)[1],
               "failed" if res.failed else "ok", 1000 * t_ours]
        if small_gicp is not None:
            target = B.vertices[B.valid]
            T0 = np.eye(4)
            T0[:3, :3], T0[:3, 3] = A.R.T, -A.R.T @ A.t
            out, t_theirs = timed_median(lambda: small_gicp.align(
                target, src.points, T0, "PLANE_ICP", downsampling_resolution=0.005, max_correspondence_distance=0.05,
                num_threads=1, max_iterations=cfg.max_iterations, rotation_epsilon=np.deg2rad(cfg.converge_rot_deg),
                translation_epsilon=cfg.converge_trans), runs)
            R = out.T_target_source[:3, :3].T
            moved_m, moved_deg = step_from(B.R, B.t, R, -R @ out.T_target_source[:3, 3])
            row += [1000 * moved_m, moved_deg, 1000 * t_theirs]
        if o3d is not None:
            row += open3d_row(o3d, A, B, src, runs, cfg)
        rows.append(row + [load()])
    headers = ["pair k->k+1", "ours mm", "ours deg", "ours", "ours ms"]
    if small_gicp is not None:
        headers += ["small_gicp mm", "small_gicp deg", "small_gicp ms"]
    if o3d is not None:
        headers += ["Open3D mm", "Open3D deg", "Open3D ms"]
    print_table(headers + ["load"], rows)
    for name, module in (("small_gicp", small_gicp), ("Open3D", o3d)):
        if module is None:
            print(f"per registration beside {name}: skipped, not installed (pip install -e '.[bench]')")


def optional(name: str):
    """The module ``name``, or None when it is not installed."""
    try:
        return __import__(name)
    except ImportError:
        return None


def open3d_row(o3d, A, B, src, runs: int, cfg) -> list:
    """Open3D's point-to-plane ICP of ``src`` (world) to frame ``B`` (its camera, our normals) from
    frame ``A``'s pose: [mm, deg, ms] to ``B``'s true pose."""
    from assocbench.tracks.dense.icp import step_from

    reg = o3d.pipelines.registration
    ok = B.valid
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(B.vertices[ok])))
    target.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(B.normals[ok]))
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(src.points)))
    T0 = np.eye(4)
    T0[:3, :3], T0[:3, 3] = A.R.T, -A.R.T @ A.t
    out, elapsed = timed_median(lambda: reg.registration_icp(
        source, target, 0.05, T0, reg.TransformationEstimationPointToPlane(),
        reg.ICPConvergenceCriteria(1e-6, 1e-6, cfg.max_iterations)), runs)
    T = np.asarray(out.transformation)
    R = T[:3, :3].T
    moved_m, moved_deg = step_from(B.R, B.t, R, -R @ T[:3, 3])
    return [1000 * moved_m, moved_deg, 1000 * elapsed]


def timed_median(fn, runs: int) -> tuple[object, float]:
    """(the last result, the median wall time in seconds) of ``runs`` calls of ``fn``."""
    times, out = [], None
    for _ in range(runs):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return out, float(np.median(times))


if __name__ == "__main__":
    run_recorded(main)
