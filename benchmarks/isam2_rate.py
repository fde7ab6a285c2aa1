"""Frame time of the iSAM2 back end (``PlanarISAM2``) against the number of mapped landmarks, on one core.

A state with N landmarks is a real SLAM graph, not a synthetic covariance: posts on a 2 m grid
(N of them), a robot driving a lawnmower path over it (0.5 m steps, rows at most 6 m apart, a 360°
lidar of 5 m: 10-15 posts in view along the last row, so as many pairings a frame), odometry and range-bearing
noise as in tests/planar_synth.py, the true association, landmarks made as the loop makes them.
Once every post is mapped the robot drives on along the last row and back and each of the next
``--frames`` frames is timed. Columns (milliseconds, median over those frames):

* ``frame``: ``predict`` + ``problem`` + ``update`` + reading the pose (which sends the frame's
  factors to iSAM2): everything the back end does in a frame of the closed loop;
* ``isam2 update``: the ``ISAM2.update`` calls alone (measurement factors, then odometry);
* ``ISAM2 query``: ``PlanarISAM2.joint_covariance`` of the pose and the frame's candidates (the
  query behind the problem's P) with ``joint="isam2"`` (the default: ``ISAM2.jointMarginalCovariance``);
* ``elimination``: the same with ``joint="elimination"`` (the linearised graph eliminated with
  those keys last);
* ``Marginals (batch)``: the same joint covariance from ``gtsam.Marginals`` on the whole graph
  (relinearised and refactored from scratch: what a non-incremental query would cost);
* ``poses``, ``pairings``: the graph's size and the median pairings per timed frame.

Usage: python benchmarks/isam2_rate.py [--frames 30] [--landmarks 50 200 500]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as figures are stated

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402

from assocbench.estimators.base import FrameData, Motion  # noqa: E402
from assocbench.estimators.config import EstimatorConfig  # noqa: E402
from assocbench.estimators.planar_isam2 import PlanarISAM2, import_gtsam  # noqa: E402
from assocbench.models.range_bearing import predict, wrap  # noqa: E402

SPACING, STEP, ROW_GAP, MAX_RANGE, FOV = 2.0, 0.5, 6.0, 5.0, 2 * np.pi
R_MEAS = np.diag([0.02, np.deg2rad(0.5)]) ** 2
Q_ODOM = np.diag([0.01, 0.01, np.deg2rad(0.3)]) ** 2


def grid_posts(n: int) -> np.ndarray:
    """n posts on a 2 m grid, about twice as wide as deep."""
    ny = max(1, int(round(np.sqrt(n / 2))))
    nx = int(np.ceil(n / ny))
    return np.array([[SPACING * i, SPACING * j] for j in range(ny) for i in range(nx)])[:n]


def lawnmower(posts: np.ndarray, extra: int) -> np.ndarray:
    """Poses (K, 3) along rows 6 m apart over the posts (heading along the row), then ``extra``
    more steps back and forth along the last row."""
    x0, x1 = posts[:, 0].min() - 1, posts[:, 0].max() + 1
    y0, y1 = posts[:, 1].min() + 1, posts[:, 1].max() - 1
    rows = np.linspace(y0, y1, int(np.ceil((y1 - y0) / ROW_GAP)) + 1) if y1 > y0 else np.array([y0])
    pts = []
    for r, y in enumerate(rows):
        xs = np.arange(x0, x1, STEP) if r % 2 == 0 else np.arange(x1, x0, -STEP)
        pts += [(x, y, 0.0 if r % 2 == 0 else np.pi) for x in xs]
        if r + 1 < len(rows):   # the turn: up to the next row, heading +y
            pts += [(pts[-1][0], yy, np.pi / 2) for yy in np.arange(y, rows[r + 1], STEP)]
    last = pts[-len(np.arange(x0, x1, STEP)):]
    while extra > 0:
        last = [(x, y, wrap(th + np.pi)) for x, y, th in last[::-1]]
        pts += last[:extra]
        extra -= len(last)
    return np.array(pts, dtype=float)


def between(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    c, s = np.cos(p0[2]), np.sin(p0[2])
    d = p1[:2] - p0[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], wrap(p1[2] - p0[2])])


def frame_data(pose: np.ndarray, posts: np.ndarray, rng) -> tuple[FrameData, np.ndarray]:
    """Noisy range-bearing of the posts in the lidar's range and field of view, and their labels."""
    zhat = predict(pose, posts)
    seen = np.flatnonzero((zhat[:, 0] < MAX_RANGE) & (np.abs(zhat[:, 1]) < FOV / 2))
    z = zhat[seen] + rng.multivariate_normal(np.zeros(2), R_MEAS, len(seen))
    z[:, 1] = wrap(z[:, 1])
    return FrameData(z, np.repeat(R_MEAS[None], len(seen), axis=0)), seen


def isam2_frame_rate(n_landmarks: int, frames: int = 30, seed: int = 0) -> dict:
    """Build the SLAM graph of ``n_landmarks`` posts, then time ``frames`` more frames (module docstring)."""
    gtsam = import_gtsam()
    rng = np.random.default_rng([seed, n_landmarks, 14])
    posts = grid_posts(n_landmarks)
    poses = lawnmower(posts, frames + 5)
    cfg = EstimatorConfig(name="isam2", mode="slam", max_landmarks=n_landmarks + 100, max_new_per_frame=50,
                          target_paired=50)
    est = PlanarISAM2(cfg, poses[0], np.zeros((3, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), MAX_RANGE, FOV)
    isam_update = _timed_isam_update(est)
    tie: dict[int, int] = {}
    timed_from = len(poses) - frames
    rows_out = {"frame": [], "isam2 update": [], "ISAM2 query": [], "elimination": [], "pairings": []}
    for k in range(len(poses)):
        data, labels = frame_data(poses[k], posts, rng)
        timing = k >= timed_from
        isam_update.spent = 0.0
        start = time.perf_counter()
        if k:
            inc = between(poses[k - 1], poses[k]) + rng.multivariate_normal(np.zeros(3), Q_ODOM)
            est.predict(Motion(inc, Q_ODOM))
        problem = est.problem(data)
        paused = time.perf_counter()
        if timing:   # the joint queries on the state problem() saw, outside the frame's time
            rows_out["ISAM2 query"].append(_time_joint(est, problem, "isam2"))
            rows_out["elimination"].append(_time_joint(est, problem, "elimination"))
        resumed = time.perf_counter()
        where = {int(p): i for i, p in enumerate(labels)}
        a = np.array([where.get(tie.get(int(m), -2), -1) for m in problem.landmark_ids], dtype=np.int64)
        est.update(a)
        est.pose  # noqa: B018 - reading it sends this frame's measurement factors to iSAM2
        if timing:
            rows_out["frame"].append(time.perf_counter() - resumed + paused - start)
            rows_out["isam2 update"].append(isam_update.spent)
            rows_out["pairings"].append(int(np.sum(a >= 0)))
        free = np.setdiff1d(np.arange(len(data.z)), a[a >= 0])
        for map_id, i in est.initialise(data, free):
            tie[map_id] = int(labels[i])
    batch = _time_batch_marginals(gtsam, est, problem)
    ms = {key: 1e3 * float(np.median(v)) for key, v in rows_out.items() if key != "pairings"}
    return {"landmarks": len(est.book), "poses": est.frame + 1, "pairings": int(np.median(rows_out["pairings"])),
            **ms, "Marginals (batch)": 1e3 * batch}


def _timed_isam_update(est: PlanarISAM2):
    """Wrap the estimator's ``ISAM2.update`` to add up the seconds spent in it."""
    isam = est.isam

    class Timed:
        spent = 0.0

        def __getattr__(self, name):
            return getattr(isam, name)

        def update(self, *args):
            start = time.perf_counter()
            out = isam.update(*args)
            Timed.spent += time.perf_counter() - start
            return out

    est.isam = Timed()
    return Timed


def _candidate_rows(est: PlanarISAM2, problem) -> np.ndarray:
    index = {m: r for r, m in enumerate(est.book.ids)}
    return np.array([index[int(m)] for m in problem.landmark_ids if int(m) in index], dtype=np.int64)


def _time_joint(est: PlanarISAM2, problem, joint: str) -> float:
    rows = _candidate_rows(est, problem)
    est.joint = joint
    start = time.perf_counter()
    est.joint_covariance(rows)
    seconds = time.perf_counter() - start
    est.joint = "isam2"
    return seconds


def _time_batch_marginals(gtsam, est: PlanarISAM2, problem) -> float:
    """Median of 3: gtsam.Marginals on the whole graph, then the same joint query."""
    rows = _candidate_rows(est, problem)
    keys = [gtsam.symbol("x", est.frame)] + [gtsam.symbol("l", est.book.ids[r]) for r in rows]
    times = []
    for _ in range(3):
        start = time.perf_counter()
        gtsam.Marginals(est.isam.getFactorsUnsafe(), est.isam.calculateEstimate()).jointMarginalCovariance(keys)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--landmarks", type=int, nargs="+", default=[50, 200, 500])
    args = parser.parse_args()
    headers = ["landmarks", "poses", "pairings", "frame", "isam2 update", "ISAM2 query", "elimination",
               "Marginals (batch)"]
    rows = []
    for n in args.landmarks:
        r = isam2_frame_rate(n, args.frames)
        rows.append([r[h] for h in headers])
    print(f"PlanarISAM2, one frame (ms, median over {args.frames} frames; one core)")
    print_table(headers, rows)


if __name__ == "__main__":
    run_recorded(main)
