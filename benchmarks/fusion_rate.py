"""Point-based fusion of one 320x240 depth frame into point maps of about 50k, 200k and 500k points,
on one core: the compiled ``point_fusion.fuse`` against the same fusion in plain vectorised numpy
(``tests/fusion_reference.fuse_numpy``), in the same process on the same maps and frame.

The maps are real fusion output: the synthetic room corner of the tests (``tests/dense_world``,
axial noise 0.0012 + 0.0019 z², normals of the 5x5-smoothed depth unless ``--raw-normals``) fused
from a camera panning over 116°; one sweep holds ~330k points, so sweeps with independent noise are
stacked (the 500k map holds the room about 1.5 times over) and subsampled at random to each size.
Each run fuses one further frame into a fresh copy of the map (the copy, with room reserved for the
frame's pixels as a grown map has, is not timed).

Columns: map size, median and p95 ms per frame over ``--runs`` runs of each, the numpy/compiled
ratio of the medians, and the points merged/added/removed in the fused frame.

Usage: python benchmarks/fusion_rate.py [--runs 25] [--sizes 50000 200000 500000] [--raw-normals]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import dense_world as dw  # noqa: E402
from fusion_reference import NumpyMap, fuse_numpy  # noqa: E402

from assocbench.tracks.dense.fusion import PointMap, fuse, warm_fusion  # noqa: E402
from assocbench.tracks.dense.settings import FusionConfig


def sweep(seed: int, frames: int, cfg: FusionConfig, smooth: bool) -> PointMap:
    """The room corner fused from a camera panning 4° per frame from 40° left to 76° right and back."""
    model, data = dw.world()
    pmap = PointMap()
    for k in range(frames):
        R, t = dw.pose(k, 0.01, -40.0 + 4.0 * (k % 30))
        fuse(pmap, dw.frame(model, data, R, t, np.random.default_rng([seed, k, 17]), smooth=smooth), R, t, k, cfg)
    return pmap


def big_map(target: int, cfg: FusionConfig, smooth: bool) -> tuple[PointMap, object, int]:
    """Sweeps with independent noise (one holds ~330k points with smoothed normals), stacked until
    they hold ``target`` points, and the frame to time (a view of the back wall and the crate)."""
    frames, maps = 60, []
    while sum(map(len, maps)) < target:
        maps.append(sweep(len(maps), frames, cfg, smooth))
    names = ("positions", "normals", "weights", "last_seen", "true_points", "geom")
    full = PointMap.from_arrays(*(np.concatenate([getattr(m, a) for m in maps]) for a in names))
    model, data = dw.world()
    R, t = dw.pose(frames, 0.01, 10.0)
    return full, dw.frame(model, data, R, t, np.random.default_rng([99, frames, 17]), smooth=smooth), frames


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
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=25)
    ap.add_argument("--sizes", type=int, nargs="+", default=[50_000, 200_000, 500_000])
    ap.add_argument("--raw-normals", action="store_true", help="normal_map of the raw depth (see FusionConfig)")
    args = ap.parse_args()
    cfg = FusionConfig()
    warm_fusion()
    full, frame, k = big_map(max(args.sizes), cfg, not args.raw_normals)
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
    normals = "raw normal_map" if args.raw_normals else "smoothed normals"
    print(f"fusion of one {w}x{h} frame (synthetic room corner, {normals}, FusionConfig defaults), "
          f"median/p95 of {args.runs} runs, one core")
    print_table(["map points", "fuse ms", "p95", "numpy ms", "p95", "numpy/fuse", "merged", "added", "removed"], rows)


if __name__ == "__main__":
    run_recorded(main)
