"""``assocbench check``: exit 1 unless every row of the suite was compared and none regressed."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import pandas as pd

from ..errors import UserError
from ..harness.check import baseline_columns, check_tolerance, compare, read_baseline, write_ok_table
from ..harness.suite import Suite, load_suite, resolve_suite, suite_requirements
from ..harness.sweep import run_suite
from ..scoring.aggregate import leaderboard_table
from ..tracks.base import GuardedMetric
from ..tracks.capabilities import OwnLeaderboard, has
from ..tracks.registry import iter_tracks
from .common import check_cache, check_output_folder, print_table

NAME = "check"
HELP = "guard accuracy in CI: compare a small suite with a clone's results/baseline*.csv (run from its root)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", help="suite YAML or shipped suite name (default: every track's CI suites, "
                   "assocbench list suites; one that needs a missing package is skipped, saying so)")
    p.add_argument("--baseline", help="baseline CSV (default: results/baseline.csv for ci, "
                   "results/baseline_<suite>.csv for another suite; without --suite it is the ci suite's)")
    p.add_argument("--tolerance", type=float, help="allowed drop of each metric (default: the suite's, else 0.02)")
    p.add_argument("--update", action="store_true", help="rewrite the baseline from this run")
    p.add_argument("--jobs", type=int, default=1, help="local worker processes")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no line per suite: only failures "
                   "and the one-line summary")


def default_suites() -> list[str]:
    """Every registered track's CI suites (``Track.suites``, ``ci``), in the registry's order."""
    return [name for track in iter_tracks() for name, entry in track.suites().items() if entry.ci]


def runnable(paths: list[Path], named: bool, quiet: bool = False) -> tuple[list[Path], dict[str, str]]:
    """The suite files that can run here, and why each other one cannot (a module it ``requires``
    is missing): skipped with a line saying so (the summary names it under ``quiet``), or refused
    when it was named (``--suite``)."""
    out, skipped = [], {}
    for path in paths:
        why = suite_requirements(path)
        if why and named:
            raise UserError(f"suite {path.stem} cannot run here: {why}")
        if why:
            skipped[path.stem] = why
            if not quiet:
                print(f"{path.stem} skipped: {why}")
        else:
            out.append(path)
    return out, skipped


def default_baseline(suite_name: str) -> Path:
    """``results/baseline.csv`` for the ci suite, ``results/baseline_<name>.csv`` for others."""
    return Path("results/baseline.csv" if suite_name == "ci" else f"results/baseline_{suite_name}.csv")


def main(args: argparse.Namespace) -> int:
    if args.suite:
        suites = [args.suite]
    else:   # --baseline alone names the ci suite's baseline, as it always did
        suites = ["ci"] if args.baseline is not None else default_suites()
    paths, skipped = runnable([resolve_suite(s) for s in suites], named=bool(args.suite), quiet=args.quiet)
    loaded = [load_suite(path) for path in paths]
    # every suite and baseline checked before any suite runs: a missing last baseline must not
    # be found only after the first suites ran for minutes
    baselines = [baseline_of(suite, args) for suite in loaded]
    check_cache(*(suite.first_source() for suite in loaded))
    codes = [check_suite(suite, path, baseline, args) for suite, (path, baseline) in zip(loaded, baselines)]
    if args.quiet:   # the line per suite (and per skipped suite) left out above, in one
        print(summary(loaded, codes, skipped, [path for path, _ in baselines] if args.update else None))
    return max(codes, default=0)


def summary(suites: list[Suite], codes: list[int], skipped: dict[str, str], written: list[Path] | None) -> str:
    """The one line ``check --quiet`` ends with, in place of a line per suite: what was compared
    (or written, with ``--update``), which suites failed, which were skipped and why."""
    skip = "".join(f"; {name} skipped: {why}" for name, why in skipped.items())
    if written is not None:
        return f"wrote {len(written)} baseline(s): {', '.join(map(str, written))}{skip}"
    failed = [suite.name for suite, code in zip(suites, codes) if code]
    if failed:
        return f"check failed: {len(failed)} of {len(suites)} suite(s) ({', '.join(failed)}){skip}"
    rows = sum(len(suite.rows()) for suite in suites)
    names = ", ".join(suite.name for suite in suites)
    return f"ok: {rows} scenario × method rows compared in {len(suites)} suite(s) ({names}), all within tolerance{skip}"


def baseline_of(suite: Suite, args: argparse.Namespace) -> tuple[Path, pd.DataFrame | None]:
    """The baseline's path and its table (None with ``--update``, whose folder must be writable)."""
    path = Path(args.baseline) if args.baseline else default_baseline(suite.name)
    if args.update:
        check_output_folder(path.parent, "--baseline")   # before the suite runs, not after
        return path, None
    return path, read_baseline(path, suite.guards(), suite.name, default=args.baseline is None)


def check_suite(suite: Suite, baseline_path: Path, baseline: pd.DataFrame | None, args: argparse.Namespace) -> int:
    """Run one suite and compare it with its ``baseline`` (None: rewrite the baseline at
    ``baseline_path``): exit status. The columns compared are the suite's track's
    (``Track.guards``)."""
    tolerance = check_tolerance(suite.tolerance if args.tolerance is None else args.tolerance)
    tolerances = suite.tolerances() | {"tolerance": tolerance}
    guards = suite.guards()
    with tempfile.TemporaryDirectory(prefix="assocbench-check-") as scratch:  # always a fresh run
        summaries, _ = run_suite(suite, Path(scratch), args.jobs, progress=not args.quiet)
    track = suite.track_impl
    table = track.leaderboard_table(summaries) if has(track, OwnLeaderboard) else leaderboard_table(summaries)
    if args.update:
        write_ok_table(table, baseline_columns(guards), baseline_path)
        if not args.quiet:
            print(f"wrote baseline {baseline_path} ({len(table)} rows)")
        return 0
    expected = suite.rows()
    findings = compare(table, baseline, guards, tolerances, expected)
    if len(findings):
        print(f"check failed: {len(findings)} finding(s) against {baseline_path} ({tolerance_text(guards, tolerances)}):")
        print_table(findings, "table")
        return 1
    if not args.quiet:
        print(f"ok: {len(expected)} scenario × method rows compared with {baseline_path}, all within tolerance "
              f"({tolerance_text(guards, tolerances)})")
    return 0


def tolerance_text(guards: tuple[GuardedMetric, ...], tolerances: dict[str, float]) -> str:
    """What each guarded column may do, in its unit: ``tolerance`` on shares, ``ate_tolerance`` (m)
    times the column's ``scale`` (1000: mm), so no figure reads as another column's."""
    parts: dict[str, list[str]] = {}
    for g in guards:
        value = tolerances[g.tolerance] * g.scale
        unit = "" if g.tolerance == "tolerance" else {1.0: " m", 1000.0: " mm"}.get(g.scale, f" (m × {g.scale:g})")
        parts.setdefault(f"may {'fall' if g.higher_better else 'rise'} by {value:g}{unit}", []).append(g.name)
    return "; ".join(f"{', '.join(names)} {rule}" for rule, names in parts.items())
