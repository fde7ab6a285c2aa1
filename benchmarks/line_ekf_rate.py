"""Association + EKF localisation rate of the lines track on one core, per frame.

The world is tests/line_synth_seq.py's room (no MuJoCo): 8 × 6 m with a pillar, 8 map lines, a
200-frame lap, a 360° 6 m lidar whose extracted lines carry σ_α 0.5°, σ_r 1 cm, planar odometry
σ 1 cm, 0.3° per step. Each run starts a fresh ``LineEKF`` (first pose drawn from 5 cm, 1°) and
drives the whole lap: per frame ``predict`` (odometry), ``problem`` (candidates, ẑ, P = H P Hᵀ),
the method's ``associate`` on that problem and ``update`` with its answer; ``--clutter`` extra
lines uniform over α × r are appended to each frame (``LinesSensor``'s draw). Figures: per stage
the median ms per frame over all frames of all runs, and frames/s = frames / (run's total time),
the median over ``--runs`` runs (each run after one untimed warm-up run).

Usage: python benchmarks/line_ekf_rate.py [--runs 20] [--clutter 0 10] [--methods mnn jcbb]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the targets are stated

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))   # the tests' synthetic room, shared
from line_synth_seq import line_seq  # noqa: E402

from assocbench import make_associator  # noqa: E402
from assocbench.estimators.base import FrameData  # noqa: E402
from assocbench.estimators.config import EstimatorConfig  # noqa: E402
from assocbench.tracks.lines.belief import clutter_lines  # noqa: E402
from assocbench.tracks.lines.ekf import LineEKF  # noqa: E402

STAGES = ("predict", "problem", "associate", "update")


def frames_with_clutter(seq, clutter: int) -> list[FrameData]:
    """Each frame's extracted lines plus ``clutter`` clutter lines (seeded per frame)."""
    out = []
    for k in range(len(seq)):
        cz, cR = clutter_lines(np.random.default_rng([0, k, 101]), clutter, seq.nominal_R, seq.max_range, seq.fov)
        out.append(FrameData(np.vstack([seq.z[k], cz]), np.concatenate([seq.R[k], cR])))
    return out


def one_run(seq, frames: list[FrameData], associator, seed: int) -> tuple[dict[str, list[float]], float]:
    """Per-stage seconds of each frame and the run's total seconds."""
    P0 = np.diag([0.05 ** 2, 0.05 ** 2, np.deg2rad(1.0) ** 2])
    x0 = seq.poses[0] + np.random.default_rng([seed, 7]).multivariate_normal(np.zeros(3), P0)
    ekf = LineEKF(EstimatorConfig(), x0, P0, seq.lines, seq.segments, seq.segment_line, seq.segment_normal,
                  np.arange(len(seq.lines)), seq.max_range, seq.fov)
    times: dict[str, list[float]] = {s: [] for s in STAGES}
    total = 0.0
    for k, frame in enumerate(frames):
        t0 = time.perf_counter()
        if k:
            ekf.predict(seq.motions[k])
        t1 = time.perf_counter()
        problem = ekf.problem(frame)
        t2 = time.perf_counter()
        association = associator.associate(problem)
        t3 = time.perf_counter()
        ekf.update(association)
        t4 = time.perf_counter()
        for stage, dt in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            times[stage].append(dt)
        total += t4 - t0
    return times, total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--clutter", type=int, nargs="+", default=[0, 10])
    ap.add_argument("--methods", nargs="+", default=["mnn", "jcbb"])
    args = ap.parse_args()
    seq = line_seq(200, seed=0)
    rows = []
    for clutter in args.clutter:
        frames = frames_with_clutter(seq, clutter)
        for method in args.methods:
            associator = make_associator(method)
            one_run(seq, frames, associator, seed=0)   # warm-up: compiled kernels, caches
            stage_s: dict[str, list[float]] = {s: [] for s in STAGES}
            rates = []
            for run in range(args.runs):
                times, total = one_run(seq, frames, associator, seed=run)
                for s in STAGES:
                    stage_s[s] += times[s]
                rates.append(len(frames) / total)
            med = [float(np.median(stage_s[s]) * 1e3) for s in STAGES]
            rows.append([method, clutter, f"{np.mean([f.z.shape[0] for f in frames]):.1f}", *med, sum(med),
                         f"{np.median(rates):.0f}"])
    print(f"lines track, synthetic room: {len(seq)} frames x {args.runs} runs, one core")
    print_table(["method", "clutter", "lines/frame", *(f"{s} ms" for s in STAGES), "sum ms", "frames/s"], rows)


if __name__ == "__main__":
    run_recorded(main)
