"""``assocbench export``: a suite's labelled problems as a Parquet dataset with its card."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..harness.export import DRIVES, check_export_folder, export_suite
from ..harness.suite import load_suite, resolve_suite
from .common import check_cache, check_output_folder

NAME = "export"
HELP = "write a suite's problems and their truth as a Parquet dataset (problems.parquet, card.yaml)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", required=True, help="suite YAML or shipped suite name, of a track whose frames are association problems")
    p.add_argument("--out", required=True, help="a new or empty folder")
    p.add_argument("--drive", default="open", metavar="|".join(DRIVES) + "|METHOD",
                   help="open: beliefs sampled around the truth (default); oracle: a closed-loop suite's own "
                        "estimator driven by the true association; METHOD: driven by that method of the suite "
                        "(the problems its own errors lead to)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def main(args: argparse.Namespace) -> int:
    out = check_export_folder(check_output_folder(Path(args.out)))
    check_cache(load_suite(resolve_suite(args.suite)).first_source())   # before the suite renders
    progress = (lambda line: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    card = export_suite(args.suite, out, progress, args.drive)
    sizes = card["sizes"]
    mb = sizes["bytes"] / 1e6
    made_by = "belief sampling" if args.drive == "open" else f"the closed loop driven by {args.drive}"
    print(f"wrote {out}: {sizes['frames']} frames, {mb:.2f} MB, in {card['seconds']:.1f} s "
          f"({sizes['frames'] / max(card['seconds'], 1e-9):.1f} frames/s, rendering and {made_by} included)")
    return 0
