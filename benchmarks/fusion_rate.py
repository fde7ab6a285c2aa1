"""Point-based fusion of one 320x240 depth frame into point maps of about 50k, 200k and 500k points,
on one core: the compiled ``point_fusion.fuse`` against the same fusion in plain vectorised numpy
(``tests/fusion_reference.fuse_numpy``), in the same process on the same maps and frame.

The maps are real fusion output: the synthetic room corner of the tests (``tests/dense_world``,
axial noise 0.0012 + 0.0019 z²) fused from a panning camera until it holds 500k+ points, then
subsampled at random to each size. Each run fuses one further frame into a fresh copy of the map
(the copy, with room reserved for the frame's pixels as a grown map has, is not timed).

Columns: map size, median and p95 ms per frame over ``--runs`` runs of each, the numpy/compiled
ratio of the medians, and the points merged/added/removed in the fused frame.

Usage: python benchmarks/fusion_rate.py [--runs 25] [--sizes 50000 200000 500000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _util import print_table, summary_ms

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import dense_world as dw  # noqa: E402
from fusion_reference import NumpyMap, fuse_numpy  # noqa: E402

from assocbench.estimators.point_fusion import FusionConfig, PointMap, fuse, warm_fusion  # noqa: E402


def big_map(target: int, cfg: FusionConfig) -> tuple[PointMap, object, int]:
    """Fuse frames of a camera panning 3° per frame until the map holds ``target`` points; returns
    the map, the next frame (the one to time) and its index."""
    model, data = dw.world()
    pmap, k = PointMap(), 0
    while True:
        R, t = dw.pose(k, 0.01, -25.0 + 3.0 * (k % 20))
        frame = dw.frame(model, data, R, t, np.random.default_rng([0, k, 17]))
        if len(pmap) >= target:
            return pmap, frame, k
        fuse(pmap, frame, R, t, k, cfg)
        k += 1


def subsample(pmap: PointMap, size: int, seed: int) -> PointMap:
    keep = np.sort(np.random.default_rng([seed, size]).choice(len(pmap), size, replace=False))
    return PointMap.from_arrays(*(getattr(pmap, a)[keep] for a in ("positions", "normals", "weights", "last_seen",
                                                                     "true_points", "geom")))


def time_runs(setup, call, runs: int) -> tuple[list[float], object]:
    """Wall seconds of ``call(setup())`` over ``runs`` runs (setup untimed), and the last result."""
    times, out = [], None
    for _ in range(runs):
        arg = setup()
        start = time.perf_counter()
        out = call(arg)
        times.append(time.perf_counter() - start)
    return times, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=25)
    ap.add_argument("--sizes", type=int, nargs="+", default=[50_000, 200_000, 500_000])
    args = ap.parse_args()
    cfg = FusionConfig()
    warm_fusion()
    full, frame, k = big_map(max(args.sizes), cfg)
    h, w = frame.depth.shape
    rows = []
    for size in args.sizes:
        base = subsample(full, size, 1)

        def fresh():
            m = base.copy()
            m.reserve(h * w)
            return m

        compiled, st = time_runs(fresh, lambda m: fuse(m, frame, frame.R, frame.t, k, cfg), args.runs)
        plain, _ = time_runs(lambda: NumpyMap.of(base), lambda m: fuse_numpy(m, frame, frame.R, frame.t, k, cfg),
                             args.runs)
        (cm, cp), (pm, pp) = summary_ms(compiled), summary_ms(plain)
        rows.append([size, cm, cp, pm, pp, f"{pm / cm:.1f}x", st.merged, st.added, st.removed])
    print(f"fusion of one {w}x{h} frame (synthetic room corner, FusionConfig defaults), "
          f"median/p95 of {args.runs} runs, one core")
    print_table(["map points", "fuse ms", "p95", "numpy ms", "p95", "numpy/fuse", "merged", "added", "removed"], rows)


if __name__ == "__main__":
    main()
