"""Time per frame of the planar back ends (``predict`` + ``problem`` + ``update`` with ~12 paired
range-bearing measurements) against the number of landmarks in the state, on one core.

The state is synthetic (no MuJoCo): N landmarks, ``--paired`` of them 1.5-3 m around the robot's
path (the problem's candidates; all paired with their true measurement) and the rest 15-60 m away
(outside the 5 m range: they cost state size, not measurements). The starting covariance is a
random positive definite one with correlated landmarks (``A Aᵀ / d + 0.1 I``, σ ≈ 5 cm and 1°), so
the EKF's update works on a dense P as after a loop closure. The robot drives 0.1 m per frame;
each repeat builds a fresh back end (untimed), runs one frame to warm it up, then times
``--frames`` consecutive frames. Figures: the median and 95th percentile over all timed frames of
``--repeats`` repeats (ms), and frames/s from the median.

``BACKENDS`` maps a name to a factory with the constructor signature every planar back end shares,
``(cfg, pose, P, landmarks, ids, max_range, fov)``. The iSAM2 back end is timed by
``isam2_rate.py`` on a graph a SLAM run builds (a factor graph started from one dense prior, as
this script's state would be, is not one).
Usage: python benchmarks/planar_backend_rate.py [--repeats 5] [--frames 20] [--sizes 50 200 500] [--paired 12]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the targets are stated

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402
from _util import print_table, run_recorded, summary_ms  # noqa: E402

from assocbench.estimators.base import Estimator, FrameData, Motion  # noqa: E402
from assocbench.estimators.config import EstimatorConfig  # noqa: E402
from assocbench.estimators.planar_ekf import PlanarEKF  # noqa: E402
from assocbench.models.range_bearing import predict, wrap  # noqa: E402

MAX_RANGE, FOV, STEP = 5.0, 2 * np.pi, 0.1
R_MEAS = np.diag([0.02 ** 2, np.deg2rad(0.5) ** 2])

# iSAM2 is timed by isam2_rate.py on a real SLAM graph: started here from one dense joint prior
# it would be timed on a graph no SLAM run builds
BACKENDS: dict[str, Callable[..., Estimator]] = {"ekf": PlanarEKF}
NOTES: list[str] = ["isam2: see benchmarks/isam2_rate.py (a real SLAM graph, not a dense synthetic prior)"]


def random_covariance(rng: np.random.Generator, n_lm: int) -> np.ndarray:
    """PD covariance of ``[x, y, θ, l₁ … l_N]`` with correlated entries, σ ≈ 5 cm and 1°."""
    d = 3 + 2 * n_lm
    A = rng.normal(size=(d, d))
    P = A @ A.T / d + 0.1 * np.eye(d)
    s = np.full(d, 0.05)
    s[2] = np.deg2rad(1.0)
    return P * np.outer(s, s)


def make_world(seed: int, n_lm: int, n_pair: int) -> tuple[np.ndarray, np.ndarray]:
    """Landmarks (N, 2): the first ``n_pair`` 1.5-3 m from the path x ∈ [0, 2.1], the rest far away."""
    rng = np.random.default_rng([seed, n_lm, n_pair])
    near_angle, near_r = rng.uniform(-np.pi, np.pi, n_pair), rng.uniform(1.5, 3.0, n_pair)
    near = np.column_stack([1.0 + near_r * np.cos(near_angle), near_r * np.sin(near_angle)])
    far_angle, far_r = rng.uniform(-np.pi, np.pi, n_lm - n_pair), rng.uniform(15.0, 60.0, n_lm - n_pair)
    far = np.column_stack([far_r * np.cos(far_angle), far_r * np.sin(far_angle)])
    return np.vstack([near, far]), rng.normal(size=(1000, n_pair, 2))


def time_frames(name: str, seed: int, n_lm: int, n_pair: int, frames: int) -> list[float]:
    """Seconds per frame of ``frames`` consecutive frames (after one untimed) of a fresh back end."""
    rng = np.random.default_rng([seed, n_lm, 7])
    landmarks, noise = make_world(seed, n_lm, n_pair)
    cfg = EstimatorConfig(mode="slam", drop_after=10 ** 3)
    est = BACKENDS[name](cfg, np.zeros(3), random_covariance(rng, n_lm), landmarks, np.arange(n_lm), MAX_RANGE, FOV)
    motion = Motion(np.array([STEP, 0.0, 0.0]), cfg.planar_odometry_covariance)
    seconds = []
    for k in range(1, frames + 2):
        true_pose = np.array([STEP * k, 0.0, 0.0])
        z = predict(true_pose, landmarks[:n_pair]) + noise[k] * np.sqrt(np.diag(R_MEAS))
        z[:, 1] = wrap(z[:, 1])
        frame = FrameData(z, np.repeat(R_MEAS[None], n_pair, axis=0))
        start = time.perf_counter()
        est.predict(motion)
        problem = est.problem(frame)
        est.update(np.where(problem.landmark_ids < n_pair, problem.landmark_ids, -1))
        if k > 1:
            seconds.append(time.perf_counter() - start)
        assert problem.n == n_pair, f"{problem.n} candidates, expected the {n_pair} near landmarks"
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 200, 500])
    ap.add_argument("--paired", type=int, default=12)
    args = ap.parse_args()
    rows = []
    for name in BACKENDS:
        for n_lm in args.sizes:
            seconds = [s for rep in range(args.repeats) for s in time_frames(name, rep, n_lm, args.paired, args.frames)]
            median, p95 = summary_ms(seconds)
            rows.append([name, n_lm, args.paired, median, p95, round(1e3 / median)])
    print_table(["back end", "landmarks", "paired", "median ms/frame", "p95 ms", "frames/s"], rows)
    for note in NOTES:
        print(note)


if __name__ == "__main__":
    run_recorded(main)
