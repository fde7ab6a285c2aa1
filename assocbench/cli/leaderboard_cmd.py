"""``assocbench leaderboard``: run a suite and write results/leaderboard.{csv,md} and plots."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..harness.dense_suite import is_dense_suite, load_dense_suite, run_dense_suite, write_dense_leaderboard
from ..harness.leaderboard import write_leaderboard
from ..harness.suite import load_suite, resolve_suite
from ..harness.sweep import EXECUTORS, run_suite
from ..errors import UserError
from ..scoring.aggregate import OK
from .common import check_output_folder

NAME = "leaderboard"
HELP = "run every method of a suite and write the leaderboard (CSV, Markdown, PNG plots)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", help="suite YAML or shipped suite name: leaderboard (default), loop (closed loop), "
                   "planar (posts), lines (walls), dense (depth frames); the *_ci suites are check's")
    p.add_argument("--jobs", type=int, default=1, help="local worker processes")
    p.add_argument("--executor", choices=EXECUTORS, default="local", help="local processes or a dask cluster")
    p.add_argument("--address", help="dask scheduler address, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--out", help="folder for the leaderboard files and its stored jobs (default "
                   "results/runs/<suite name>; the committed reference in results/ is written with --out results)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    path = resolve_suite(args.suite or "leaderboard")
    if is_dense_suite(path):
        return dense_main(load_dense_suite(path), args)
    suite = load_suite(path)
    out = check_output_folder(Path(args.out or f"results/runs/{suite.name}"))
    summaries, frames = run_suite(suite, out, args.jobs, args.executor, args.address, progress=not args.quiet)
    paths = write_leaderboard(summaries, frames, out)
    print(paths["md"].read_text())
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    untrusted = summaries[summaries["status"] != OK]
    for _, r in untrusted.iterrows():
        error = f": {r['error']}" if r["error"] else ""
        print(f"assocbench: warning: {r['method']} on {r['scenario']} seed {r['seed']} is not ok, "
              f"{r['status']}{error}", file=sys.stderr)
    return 1 if len(untrusted) else 0


def dense_main(suite, args: argparse.Namespace) -> int:
    """A dense suite: every run in worker processes, then the leaderboard files (local only)."""
    if args.executor != "local":
        raise UserError("a dense suite runs on local worker processes (--jobs); drop --executor dask")
    out = check_output_folder(Path(args.out or f"results/runs/{suite.name}"))
    summaries, frames, pictures = run_dense_suite(suite, args.jobs, progress=not args.quiet)
    paths = write_dense_leaderboard(summaries, frames, pictures, out)
    print(paths["md"].read_text())
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    untrusted = summaries[summaries["status"] != OK]
    for _, r in untrusted.iterrows():
        print(f"assocbench: warning: {r['method']} on {r['scenario']} seed {r['seed']} is not ok, {r['status']}",
              file=sys.stderr)
    return 1 if len(untrusted) else 0
