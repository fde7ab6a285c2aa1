"""Our point-to-plane ICP beside Open3D's on the same depth frame pairs: pose error and time.

What it measures. Frame pairs (k, k + d) of the dense track's rendered sequences (320x240,
``DenseSequenceSpec(scene, depth=...)``), noise-free (``sigma_base = sigma_quad = 0``) and with the
sensor's default noise. Each pair is registered frame-to-frame from the identity motion, as the
harness's ``dense.tracking: frame`` does: source = frame k's valid points in world coordinates
(``frame_source(A, A.R, A.t)``), target = frame k + d, start = frame k's true pose.

* ours: ``icp(points, normals, B, make_dense_associator("projective"), A.R, A.t, IcpConfig())``;
* Open3D: ``registration_icp(source, target, d_thr, T0, TransformationEstimationPointToPlane(),
  ICPConvergenceCriteria(1e-6, 1e-6, 60))`` (Open3D's default criteria, with our 60 iterations at
  most) on the SAME points; the target cloud is frame B's valid vertices in B's camera frame with
  OUR normal map as its normals, so both solve the same problem up to the correspondences. A
  second table gives Open3D's own normals instead (``estimate_normals``,
  ``KDTreeSearchParamHybrid(radius=0.05, max_nn=30)``, on the same target points).

Frames. Open3D's ``transformation`` T maps source points to target points: source points are in
world coordinates, target points in B's camera frame, so T is B's world-to-camera transform
``[R_Bᵀ | −R_Bᵀ t_B]``, the quantity our ICP iterates on internally. The start is
``T0 = [R_Aᵀ | −R_Aᵀ t_A]`` and the camera-to-world pose compared with ours is
``R = T[:3, :3]ᵀ``, ``t = −R T[:3, 3]``. Errors are ``pose_error`` (tests/dense_synthetic.py)
against B's true pose; "|ours − o3d|" is the same distance between the two estimates.

Convergence. Ours: an update below 5e-3 deg and 1e-4 m, then its checks (κ, inlier share, rms,
the step from the guess); "ok" means converged and not failed. Open3D has no failure checks; it stops when fitness and
inlier rmse (point-to-POINT distance of its pairs) both change by less than 1e-6 between
iterations; "converged" here means it stopped before max_iteration. Its iteration count is read
from its Debug log in one extra untimed call.

Correspondences differ by design: ours projects each source point to its pixel and keeps the
pair when closer than 5 cm with normals within 30 deg; Open3D takes each source point's nearest
target point in 3-D within 5 cm (a KD-tree, built inside every call), with no angle test and no
field-of-view test. The column "control" is |d| between OUR solver (``icp``) with Open3D's
correspondence rule (``Open3dPairs`` below) and Open3D, both with 100x tighter stopping and 200
iterations at most (untimed), so that only where each iteration leads counts.

Time: median of ``--runs`` calls (after ``--warmup``), one thread: OPENBLAS/OMP/NUMBA threads 1
set before any import, and ``open3d.utility.set_max_threads(1)`` where Open3D has it (0.20 does);
the process CPU time over Open3D's calls divided by their wall time is printed (≤ 1: one
thread). Excluded from both: building the inputs (our ``frame_source``; numpy to
``PointCloud``). Open3D's time includes its KD-tree build on the target; its normal estimation is
timed separately ("normals ms").

Usage (open3d is a benchmark-only extra, not a test dependency):
    pip install -e '.[bench]'            # on Debian also: apt-get install libusb-1.0-0
    python benchmarks/dense_vs_open3d.py [--runs 5] [--warmup 1] [--starts 0 20 40] [--gaps 1 5 10]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"   # before numpy/open3d load: their thread pools read these once

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

try:
    import open3d as o3d
except (ImportError, OSError) as exc:   # OSError: libusb-1.0 missing on Debian
    print(f"dense_vs_open3d: open3d is not importable ({str(exc).splitlines()[0]}); "
          "pip install -e '.[bench]' (Debian also needs apt's libusb-1.0-0)", file=sys.stderr)
    sys.exit(2)

import numpy as np  # noqa: E402
from _util import print_table, run_recorded, summary_ms  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dense_synthetic import pose_error  # noqa: E402

from assocbench.associators.dense.base import DenseAssociator, Pairs  # noqa: E402
from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.models.depth_frame import DepthFrame  # noqa: E402
from assocbench.tracks.dense.icp import IcpResult, icp  # noqa: E402
from assocbench.tracks.dense.run import frame_source  # noqa: E402
from assocbench.tracks.dense.sequence import DenseSequenceSpec, load_dense_sequence  # noqa: E402
from assocbench.tracks.dense.settings import DepthConfig, IcpConfig  # noqa: E402
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402

REG = o3d.pipelines.registration
D_THR = 0.05          # both methods' correspondence gate (m): our DenseAssociator default
MAX_ITERATIONS = 60   # Open3D's cap here (its default is 30); ours stops on IcpConfig's own test (100 at most)
NORMAL_SEARCH = dict(radius=0.05, max_nn=30)
AGREE_MM, AGREE_DEG = 1.0, 0.1
# the control's stopping: 100x tighter than the defaults on both sides, 200 iterations at most
CONTROL_CONFIG = IcpConfig(max_iterations=200, converge_rot_deg=1e-5, converge_trans=1e-7)
CONTROL_CRITERIA = (1e-9, 1e-9, 200)


@dataclass
class Estimate:
    """A camera-to-world pose of the target, whether its method calls it converged, iterations."""

    R: np.ndarray
    t: np.ndarray
    ok: bool
    iterations: int
    note: str = ""


class Open3dPairs(DenseAssociator):
    """Open3D's correspondence rule, for the control column: every source point's nearest valid
    target vertex in 3-D, kept when ``|p′ − q| ≤ d_thr`` (``KDTreeFlann.SearchHybrid`` with
    max_nn 1); no normal-angle and no field-of-view filter."""

    name = "open3d-pairs"

    def associate(self, points, normals, frame: DepthFrame, R, t) -> Pairs:
        ok = frame.valid.reshape(-1)
        pixel = np.flatnonzero(ok)
        if getattr(self, "_frame", None) is not frame:   # one tree per target, as Open3D per call
            self._frame, self._tree = frame, cKDTree(frame.vertices.reshape(-1, 3)[ok])
        dist, idx = self._tree.query((points - t) @ R, distance_upper_bound=self.d_thr)
        src = np.flatnonzero(dist <= self.d_thr)
        return Pairs(src, pixel[idx[src]], len(points))


def timed(fn, runs: int, warmup: int) -> tuple[object, list[float], float]:
    """(last result, wall seconds of each timed run, process CPU seconds / wall seconds)."""
    for _ in range(warmup):
        fn()
    walls, cpu0 = [], time.process_time()
    for _ in range(runs):
        start = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - start)
    return out, walls, (time.process_time() - cpu0) / sum(walls)


def ours(result: IcpResult) -> Estimate:
    note = "" if not result.failed else result.reason.split(":")[0].split(" (")[0]
    return Estimate(result.R, result.t, result.converged and not result.failed, result.iterations, note)


def cloud(points: np.ndarray, normals: np.ndarray | None = None) -> o3d.geometry.PointCloud:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64)))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals, dtype=np.float64))
    return pc


def world_to_camera(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``[Rᵀ | −Rᵀ t]`` (4, 4): Open3D's transformation for a target in the camera of pose (R, t)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R.T, -R.T @ t
    return T


def open3d_icp(source, target, T0: np.ndarray, criteria: tuple = (1e-6, 1e-6, MAX_ITERATIONS)):
    """Open3D's point-to-plane ICP; ``criteria``: (relative_fitness, relative_rmse, max_iteration)."""
    return REG.registration_icp(source, target, D_THR, T0, REG.TransformationEstimationPointToPlane(),
                                REG.ICPConvergenceCriteria(*criteria))


def open3d_iterations(source, target, T0: np.ndarray) -> int:
    """Updates Open3D applies (its loop logs "ICP Iteration #i" at Debug level before each; the
    log goes to the C++ stdout, so file descriptor 1 is redirected for this one call)."""
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile("w+") as log:
        os.dup2(log.fileno(), 1)
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Debug)
        try:
            open3d_icp(source, target, T0)
        finally:
            o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
            os.dup2(saved, 1)
            os.close(saved)
        log.seek(0)
        return log.read().count("ICP Iteration #")


def theirs(result, iterations: int) -> Estimate:
    """Camera-to-world ``R = T₃ₓ₃ᵀ``, ``t = −R T[:3, 3]`` of Open3D's world-to-camera T."""
    T = np.asarray(result.transformation)
    R = T[:3, :3].T
    return Estimate(R, -R @ T[:3, 3], iterations < MAX_ITERATIONS, iterations)


def errors(e: Estimate, R: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """(mm, deg) between ``e`` and the pose (R, t)."""
    m, deg = pose_error(e.R, e.t, R, t)
    return 1e3 * m, deg


def agree(a: Estimate, b: Estimate) -> bool:
    mm, deg = errors(a, b.R, b.t)
    return a.ok and b.ok and mm <= AGREE_MM and deg <= AGREE_DEG


def run_pair(A: DepthFrame, B: DepthFrame, proj: DenseAssociator, runs: int, warmup: int) -> dict:
    """Every estimate and timing of one pair (see the module docstring)."""
    src = frame_source(A, A.R, A.t)
    res, t_ours, _ = timed(lambda: icp(src.points, src.normals, B, proj, A.R, A.t), runs, warmup)
    kd = ours(icp(src.points, src.normals, B, make_dense_associator("kdtree", d_thr=D_THR), A.R, A.t))
    ok, T0 = B.valid, world_to_camera(A.R, A.t)
    source, target, own = cloud(src.points), cloud(B.vertices[ok], B.normals[ok]), cloud(B.vertices[ok])
    r1, t_o3d, cpu1 = timed(lambda: open3d_icp(source, target, T0), runs, warmup)
    # the control, both run far past their default stopping points so that only the fixed point counts
    same = ours(icp(src.points, src.normals, B, Open3dPairs(d_thr=D_THR), A.R, A.t, CONTROL_CONFIG))
    tight = theirs(open3d_icp(source, target, T0, CONTROL_CRITERIA), 0)
    search = o3d.geometry.KDTreeSearchParamHybrid(**NORMAL_SEARCH)
    _, t_norm, cpu2 = timed(lambda: own.estimate_normals(search), runs, 0)
    r2, t_o3d2, cpu3 = timed(lambda: open3d_icp(source, own, T0), runs, warmup)
    return dict(ours=ours(res), kd=kd, same=same, tight=tight, o3d=theirs(r1, open3d_iterations(source, target, T0)),
                o3d_own=theirs(r2, open3d_iterations(source, own, T0)), ms_ours=summary_ms(t_ours)[0],
                ms_o3d=summary_ms(t_o3d)[0], ms_norm=summary_ms(t_norm)[0], ms_o3d_own=summary_ms(t_o3d2)[0],
                cpu=max(cpu1, cpu2, cpu3), pairs=len(src.points))


def rows_for(key: tuple, A: DepthFrame, B: DepthFrame, r: dict) -> tuple[list, list]:
    """One row of each table for the pair ``key = (scene, noise, k, d)``."""
    o, t1, t2 = r["ours"], r["o3d"], r["o3d_own"]
    motion, e_o, e_1, e_2 = errors(Estimate(A.R, A.t, True, 0), B.R, B.t), errors(o, B.R, B.t), \
        errors(t1, B.R, B.t), errors(t2, B.R, B.t)
    d1, d2, d21, ds = errors(o, t1.R, t1.t), errors(o, t2.R, t2.t), errors(t2, t1.R, t1.t), errors(r["same"], r["tight"].R, r["tight"].t)
    row1 = [*key, *motion, *e_o, *e_1, *d1, r["ms_ours"], r["ms_o3d"], o.iterations, t1.iterations,
            o.note or "ok", "yes" if t1.ok else "no", f"{ds[0]:.3f}/{ds[1]:.4f}"]
    row2 = [*key, *e_2, *d2, *d21, r["ms_norm"], r["ms_o3d_own"], t2.iterations, "yes" if t2.ok else "no"]
    return row1, row2


def summary(results: list[dict], which: str) -> str:
    both = sum(r["ours"].ok and r[which].ok for r in results)
    close = sum(agree(r["ours"], r[which]) for r in results)
    return (f"both converge and agree within {AGREE_MM:g} mm / {AGREE_DEG:g} deg: {close} of {len(results)} pairs "
            f"(both converge: {both}; ours ok: {sum(r['ours'].ok for r in results)}, Open3D converged: "
            f"{sum(r[which].ok for r in results)})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--scenes", nargs="+", default=["crates", "bays"])
    ap.add_argument("--starts", nargs="+", type=int, default=[0, 20, 40])
    ap.add_argument("--gaps", nargs="+", type=int, default=[1, 5, 10])
    args = ap.parse_args()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    if hasattr(o3d.utility, "set_max_threads"):   # 0.20 has it; OMP_NUM_THREADS=1 above covers older ones
        o3d.utility.set_max_threads(1)
    warm_dense()
    proj = make_dense_associator("projective", d_thr=D_THR)
    noises = {"none": DepthConfig(sigma_base=0.0, sigma_quad=0.0), "sensor": DepthConfig()}
    frames = max(args.starts) + max(args.gaps) + 1
    table1, table2, results = [], [], []
    for scene in args.scenes:
        for noise, depth in noises.items():
            seq = load_dense_sequence(DenseSequenceSpec(scene=scene, frames=frames, depth=depth))
            for k in args.starts:
                for d in args.gaps:
                    A, B = seq.frame(k), seq.frame(k + d)
                    r = run_pair(A, B, proj, args.runs, args.warmup)
                    row1, row2 = rows_for((scene, noise, k, d), A, B, r)
                    table1.append(row1)
                    table2.append(row2)
                    results.append(r)
                    print(".", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    report(table1, table2, results, args)


def report(table1: list, table2: list, results: list[dict], args) -> None:
    ratio = np.median([r["ms_o3d"] / r["ms_ours"] for r in results])
    print(f"point-to-plane ICP, ours (projective) vs Open3D {o3d.__version__} (3-D nearest neighbour), frame-to-frame "
          f"from the identity motion, 320x240 (~{int(np.median([r['pairs'] for r in results]))} source points), "
          f"gate {D_THR * 100:g} cm; median of {args.runs} runs, one thread "
          f"(Open3D CPU/wall at most {max(r['cpu'] for r in results):.2f})")
    print("\n1. Open3D with OUR normal map on the target (the same problem up to the correspondences)")
    print_table(["scene", "noise", "k", "d", "motion mm", "deg", "ours mm", "deg", "o3d mm", "deg",
                 "|ours-o3d| mm", "deg", "ours ms", "o3d ms", "ours it", "o3d it", "ours", "o3d conv",
                 "control |d| mm/deg"], table1)
    print(summary(results, "o3d"))
    same = [errors(r["same"], r["tight"].R, r["tight"].t) for r in results]
    print(f"control (same pairs): our solver on Open3D's correspondence rule vs Open3D, both iterated to "
          f"{CONTROL_CONFIG.max_iterations} at most with tight stopping: largest |d| {max(mm for mm, _ in same):.4f} mm, "
          f"{max(deg for _, deg in same):.5f} deg over {len(results)} pairs")
    kd = [agree(r["kd"], r["o3d"]) for r in results]
    print(f"ours with the kdtree associator (3-D nearest neighbour plus our angle and view filters) and Open3D "
          f"both converge and agree within {AGREE_MM:g} mm / {AGREE_DEG:g} deg: {sum(kd)} of {len(results)} pairs")
    print(f"time: Open3D / ours, median over pairs: {ratio:.1f}x\n")
    print(f"2. Open3D with its own normals (estimate_normals, radius {NORMAL_SEARCH['radius']} m, "
          f"max_nn {NORMAL_SEARCH['max_nn']})")
    print_table(["scene", "noise", "k", "d", "o3d* mm", "deg", "|ours-o3d*| mm", "deg", "|o3d-o3d*| mm", "deg",
                 "normals ms", "o3d* ms", "o3d* it", "o3d* conv"], table2)
    print(summary(results, "o3d_own"))


if __name__ == "__main__":
    run_recorded(main)
