"""Run every benchmark that writes a record, one after another, with the arguments docs/benchmarks.md shows.

Meant for a quiet machine: each script's record (benchmarks/records/) keeps the load average
before and after it, and every record of one pass carries the same commit and machine, so the
page's figures can be compared with each other. A script that fails is reported at the end and
the others still run; one whose optional dependency is absent (MRPT, Open3D) prints why and
leaves no record. Commit the records afterwards (``git add benchmarks/records``).

Usage: python benchmarks/run_all.py [--only NAME ...] [--list]
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Run:
    """One recorded run: a script, its arguments, and the record's name when a script has several."""

    script: str
    args: tuple[str, ...] = ()
    name: str = ""   # --record-as: the record is <script>.<name>.json

    @property
    def record(self) -> str:
        """The record file's name under benchmarks/records/."""
        return f"{Path(self.script).stem}{'.' + self.name if self.name else ''}.json"

    def argv(self) -> list[str]:
        return [f"benchmarks/{self.script}", *self.args, *(["--record-as", self.name] if self.name else [])]

    def command(self) -> str:
        return shlex.join(["python", *self.argv()])


# in the page's order: the heading of each group, then its runs
TOPICS: dict[str, tuple[Run, ...]] = {
    "Associators on synthetic problems": (
        Run("associator_runtime.py"),
        Run("jcbb_anytime.py"),
        Run("jcbb_vs_textbook.py"),
        Run("mrpt_compare.py", ("--sizes", "10", "20", "40", "160", "--problems", "20", "--timeout", "2")),
        Run("rjc_scale.py"),
        Run("ccda_scale.py"),
        Run("jpda_scale.py"),
        Run("learned_runtime.py"),
        Run("problem_construction.py", ("--problems", "5")),
    ),
    "Camera track": (
        Run("pipeline_fps.py"),
        Run("ekf_update_rate.py"),
        Run("dataset_rate.py"),
    ),
    "Planar and planar_log tracks": (
        Run("lidar_rate.py"),
        Run("planar_backend_rate.py"),
        Run("isam2_rate.py"),
        Run("planar_log_odometry.py"),
    ),
    "Lines track": (
        Run("line_extract_rate.py"),
        Run("line_ekf_rate.py"),
    ),
    "Dense track": (
        Run("depth_sensor_rate.py"),
        Run("dense_depth_frame.py"),
        Run("dense_icp_rate.py", ("--runs", "20")),
        Run("fusion_rate.py"),
        Run("dense_association.py"),
        Run("dense_icp_basin.py", ("--seeds", "6", "--scenes", "crates")),
        Run("dense_icp_basin.py", ("--seeds", "6", "--scenes", "crates", "--noise-free"), "noise-free"),
        Run("dense_icp_thresholds.py"),
        Run("dense_direction_share.py"),
        Run("dense_map_order.py", ("--frames", "500")),
        Run("dense_flat.py", ("--frames", "500")),
        Run("dense_flat.py", ("--frames", "500", "--scene", "bays"), "bays"),
        Run("dense_map_figure.py", ("--runs", "7")),
        Run("dense_rate.py", ("--frames", "50", "200", "500", "--baseline-frames", "200", "--map-frames", "50",
                              "--runs", "3", "--pairs", "4")),
        Run("dense_vs_open3d.py"),
    ),
    "Whole leaderboards, a first run and the tests": (
        Run("first_run.py"),
        Run("test_command.py"),
        Run("leaderboard_time.py", ("--suite", "leaderboard", "--jobs", "2")),
        Run("leaderboard_time.py", ("--suite", "loop", "--jobs", "2"), "loop"),
        Run("leaderboard_time.py", ("--suite", "planar", "--jobs", "2"), "planar"),
        Run("leaderboard_time.py", ("--suite", "lines", "--jobs", "2"), "lines"),
        Run("leaderboard_time.py", ("--suite", "dense", "--jobs", "2"), "dense"),
        Run("leaderboard_time.py", ("--suite", "real_photos", "--jobs", "2"), "real_photos"),
        Run("leaderboard_time.py", ("--suite", "real_victoria", "--jobs", "2"), "real_victoria"),
        Run("leaderboard_time.py", ("--suite", "real_victoria_open", "--jobs", "2"), "real_victoria_open"),
    ),
    "Simulation against recorded data": (
        Run("sim_vs_real.py", ("results", "results/real/photos")),
        Run("sim_vs_real.py", ("results/planar", "results/real/victoria", "--by", "backend", "--metric", "ate_rmse",
                               "f1"), "victoria"),
    ),
}

# scripts that record when run but that this pass does not run, and why
NOT_RUN = {
    "call_sizes.py": "it reads the stored runs a leaderboard folder keeps (runs/, not committed): run it after "
                     "that folder's `assocbench leaderboard --out`",
    "dense_fusion_ab.py": "it compares two checkouts given on its command line (before and after a change)",
}


def runs() -> list[Run]:
    """Every run, in the page's order."""
    return [run for group in TOPICS.values() for run in group]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", metavar="NAME",
                    help="only these runs: a script (dense_flat.py or dense_flat) or a record (dense_flat.bays)")
    ap.add_argument("--list", action="store_true", help="print the commands and exit")
    args = ap.parse_args()
    chosen = [run for run in runs() if not args.only or {run.script, Path(run.script).stem,
                                                         Path(run.record).stem} & set(args.only)]
    if args.only and not chosen:
        ap.error(f"no run named {' '.join(args.only)}; --list shows them")
    if args.list:
        print("\n".join(run.command() for run in chosen))
        return 0
    failed = []
    for k, run in enumerate(chosen, 1):
        print(f"[{k}/{len(chosen)}] {run.command()}  (load {os.getloadavg()[0]:.2f})", flush=True)
        start = time.perf_counter()
        code = subprocess.run([sys.executable, *run.argv()], cwd=ROOT).returncode
        print(f"[{k}/{len(chosen)}] exit {code} after {time.perf_counter() - start:.0f} s\n", flush=True)
        if code:
            failed.append(f"{run.command()} (exit {code})")
    print(f"{len(chosen) - len(failed)} of {len(chosen)} runs succeeded" + "".join(f"\nfailed: {f}" for f in failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
