"""``assocbench leaderboard``: run a suite and write results/leaderboard.{csv,md} and plots."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import UserError
from ..harness.leaderboard import write_card, write_leaderboard
from ..harness.suite import load_suite, resolve_suite, suite_requirements
from ..harness.sweep import EXECUTORS, run_suite
from ..scoring.aggregate import OK
from ..tracks.capabilities import OwnLeaderboard, has
from .common import check_cache, check_output_folder

NAME = "leaderboard"
HELP = "run every method of a suite and write the leaderboard (CSV, Markdown, PNG plots)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", help="suite YAML or a track's shipped suite (assocbench list suites); default: "
                   "leaderboard")
    p.add_argument("--jobs", type=int, default=1, help="local worker processes")
    p.add_argument("--executor", choices=EXECUTORS, default="local", help="local processes or a dask cluster")
    p.add_argument("--address", help="dask scheduler address, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--out", help="folder for the leaderboard files and its stored runs (default "
                   "results/runs/<suite name>; the committed reference in results/ is written with --out results)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    path = resolve_suite(args.suite or "leaderboard")
    why = suite_requirements(path)
    if why:
        raise UserError(f"suite {path.stem} cannot run here: {why}")
    suite = load_suite(path)
    check_cache(suite.first_source())
    out = check_output_folder(Path(args.out or f"results/runs/{suite.name}"))
    summaries, frames = run_suite(suite, out, args.jobs, args.executor, args.address, progress=not args.quiet,
                                  say_reused=True)
    track = suite.track_impl
    paths = track.write_leaderboard(summaries, frames, out) if has(track, OwnLeaderboard) else \
        write_leaderboard(summaries, frames, out, track, suite.scene_paths())
    paths["card"] = write_card(out, track, suite.loop)
    print(paths["md"].read_text())
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    untrusted = summaries[summaries["status"] != OK]
    for _, r in untrusted.iterrows():
        error = f": {r['error']}" if r["error"] else ""
        print(f"assocbench: warning: {r['method']} on {r['scenario']} seed {r['seed']} is not ok, "
              f"{r['status']}{error}", file=sys.stderr)
    return 1 if len(untrusted) else 0
