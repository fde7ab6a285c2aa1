"""Wall time of a whole leaderboard (--suite: a shipped suite's name or a suite file; default the camera
leaderboard): cold cache (a new sequence cache: every sequence rendered, every kernel compiled unless
NUMBA_CACHE_DIR is set) and warm cache (sequences and kernels cached, results recomputed).
Usage: python benchmarks/leaderboard_time.py [--jobs 2] [--suite assocbench/configs/leaderboard.yaml]"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _util import print_table, run_recorded

ROOT = Path(__file__).resolve().parents[1]


def timed_leaderboard(suite: str, jobs: int, cache: Path, out: Path) -> float:
    """Wall seconds of one ``assocbench leaderboard`` into ``out``. Its exit 1 (a run it could not
    measure: real_photos' CCDA past its time limit on every frame, by design) still wrote the
    leaderboard, so it is timed; any other failure stops the script."""
    env = {**os.environ, "ASSOCBENCH_CACHE": str(cache)}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "assocbench.cli.main", "leaderboard", "--suite", suite, "--jobs",
                           str(jobs), "--out", str(out), "--quiet"], env=env, stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - start
    if done.returncode not in (0, 1) or not (out / "leaderboard.csv").exists():
        sys.exit(f"leaderboard_time.py: error: the leaderboard of {suite} failed (exit {done.returncode})")
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--suite", default=str(ROOT / "assocbench" / "configs" / "leaderboard.yaml"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cold = timed_leaderboard(args.suite, args.jobs, tmp / "cache", tmp / "cold")
        warm = timed_leaderboard(args.suite, args.jobs, tmp / "cache", tmp / "warm")  # fresh results, cached frames
    print(f"leaderboard {Path(args.suite).name} with --jobs {args.jobs}, wall seconds")
    print_table(["cache", "seconds", "minutes"], [["cold", cold, cold / 60], ["warm", warm, warm / 60]])


if __name__ == "__main__":
    run_recorded(main)
