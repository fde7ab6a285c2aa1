"""The dataset's size and rates on a suite's problems (default: the camera ``ci`` suite): bytes on
disk, write rate (``DatasetWriter``: rows, Parquet encoding, zstd, fsync-free rename) and read
rate (``read_problems``: decoding and rebuilding each ``Problem`` with its checks), median of
several runs; beside them the problems' construction (rendering cached) and a round trip check.

Usage: python benchmarks/dataset_rate.py [--suite ci] [--runs 5]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

from assocbench.dataset import read_problems
from assocbench.dataset.writer import DatasetWriter
from assocbench.harness.config import run_spec
from assocbench.harness.runner import Problems
from assocbench.harness.suite import load_suite, resolve_suite


def suite_problems(name: str) -> list:
    """Every (labels, problem, truth) of the suite, in export order."""
    suite = load_suite(resolve_suite(name))
    out = []
    for cell in suite.cells:
        spec = run_spec(cell.config(suite.methods[0]))
        problems = Problems(spec.track_impl, spec.source, spec)
        for k in range(len(problems)):
            out.append(({"track": suite.track, "scene": cell.name, "difficulty": cell.difficulty, "seed": cell.seed,
                         "frame": k}, *problems[k]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="ci")
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    start = time.perf_counter()
    rows = suite_problems(args.suite)
    build = time.perf_counter() - start
    writes, reads, size = [], [], 0
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.runs):
            folder = Path(tmp) / f"run{r}"
            start = time.perf_counter()
            with DatasetWriter(folder, {"title": "rate"}) as w:
                for labels, p, t in rows:
                    w.add(labels, p, t)
            writes.append(time.perf_counter() - start)
            size = sum(f.stat().st_size for f in folder.iterdir())
            start = time.perf_counter()
            back = [item for batch in read_problems(folder) for item in batch]
            reads.append(time.perf_counter() - start)
        same = all(item.problem == p and np.array_equal(item.truth.association, t.association)
                   for item, (_, p, t) in zip(back, rows)) and len(back) == len(rows)
    n, mb = len(rows), size / 1e6
    w, r = float(np.median(writes)), float(np.median(reads))
    print(f"suite {args.suite}: {n} frames, {mb:.2f} MB on disk ({size / n / 1e3:.1f} kB per frame); "
          f"problems built (rendering cached) in {build:.2f} s; round trip identical: {same}")
    print_table(["stage", "median s", "frames/s", "MB/s (on disk)"],
                [["write", w, n / w, mb / w], ["read", r, n / r, mb / r]])


if __name__ == "__main__":
    run_recorded(main)
