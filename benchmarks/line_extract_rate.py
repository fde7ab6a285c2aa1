"""Line extraction time per scan on one core: polar, split-and-merge and RANSAC on 360-beam scans
of the synthetic 6 x 4 m room with a pillar (tests/line_synth.py), from a few poses.

Columns: median and p95 milliseconds per scan over ``--runs`` timed calls per pose (after
``--warmup`` untimed ones), the lines found, and the target (split_merge <= 0.5 ms,
ransac <= 5 ms; polar has none).

Usage: python benchmarks/line_extract_rate.py [--runs 50] [--warmup 5] [--beams 360]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from line_synth import room, synth_scan  # noqa: E402

from assocbench.tracks.lines.extract import extract_lines  # noqa: E402
from assocbench.tracks.lines.settings import LineExtractorConfig

POSES = [np.array([2.0, 1.5, 0.0]), np.array([1.2, 3.1, 2.5]), np.array([4.9, 0.9, -1.0])]
TARGET_MS = {"split_merge": "<= 0.5", "ransac": "<= 5", "polar": "-"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--beams", type=int, default=360)
    args = ap.parse_args()
    world = room()
    scans = [synth_scan(world, p, beams=args.beams, seed=k)[0] for k, p in enumerate(POSES)]
    rows = []
    for method in ("split_merge", "ransac", "polar"):
        cfg = LineExtractorConfig(method=method)
        times, found = [], []
        for s in scans:
            for _ in range(args.warmup):
                extract_lines(s, 0.01, cfg)
            for _ in range(args.runs):
                start = time.perf_counter()
                det = extract_lines(s, 0.01, cfg)
                times.append(time.perf_counter() - start)
            found.append(len(det))
        med, p95 = summary_ms(times)
        rows.append([method, args.beams, med, p95, "/".join(map(str, found)), TARGET_MS[method]])
    print(f"line extraction, {args.beams}-beam scans of the synthetic room, {len(POSES)} poses x {args.runs} runs")
    print_table(["method", "beams", "median ms", "p95 ms", "lines per pose", "target ms"], rows)


if __name__ == "__main__":
    run_recorded(main)
