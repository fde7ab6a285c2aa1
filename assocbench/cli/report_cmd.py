"""``assocbench report``: a static HTML leaderboard across tracks from leaderboard folders."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..harness.report import build_report, write_report
from ..harness.report.output import check_out

NAME = "report"
HELP = ("build a static HTML leaderboard (an overview ranking every method across tracks, a sortable, filterable "
        "page per suite with its plots) from leaderboard folders; opens from file://, no network")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folders", nargs="+", metavar="FOLDER",
                   help="leaderboard folders (each holding the leaderboard.csv that `assocbench leaderboard --out` "
                        "wrote), e.g. results results/loop")
    p.add_argument("--out", default="results/runs/report",
                   help="folder for the report: new, empty or an earlier report (its files replaced, other files "
                        "there kept); open its index.html")


def main(args: argparse.Namespace) -> int:
    out = Path(args.out)
    check_out(out)   # before reading anything, so a wrong --out is said first
    files = build_report(args.folders)
    write_report(files, out)
    pages = sum(name.endswith(".html") for name in files)
    print(f"wrote {out / 'index.html'} ({pages} pages, {len(files) - pages} pictures)")
    return 0
