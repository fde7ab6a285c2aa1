"""The point map kept in spatial order (``tracks/dense/map_order.py``) against the map left in the
order its rows were appended, over a long crates path.

Both maps fuse the same frames at their true poses, and before each fusion the model is splatted
into the previous frame's view (the source of frame-to-model tracking), as a dense run does; the
two maps are interleaved frame by frame in one process (which goes first alternates), so both see
the same machine, after the kernels are warmed. The sorted map is the default (``fuse`` sorts once the rows added or moved since
the last sort pass ``SORT_SHARE`` of the map); the baseline sets ``sort_share = None``. Sorting
changes no result (tests/tracks/dense/test_map_order.py), only which rows share a block of the
map's index: the table shows what that saves.

Columns, per hundred frames (medians; the sorted map's sorts fall in its frames and are counted):
the map's size, splat + fusion (ms a frame) unsorted and sorted, and the points the splat visited
a frame unsorted and sorted; then the sorts' count and time.

Usage: python benchmarks/dense_map_order.py [--frames 500] [--scene crates] [--share 0.1]
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):   # one core: before numpy/numba read them
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402
from dense_rate import load, render_once  # noqa: E402

from assocbench.tracks.dense import fusion  # noqa: E402
from assocbench.tracks.dense.map_order import SORT_SHARE  # noqa: E402
from assocbench.tracks.dense.prediction import Splatter  # noqa: E402
from assocbench.tracks.dense.run import view_source  # noqa: E402
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=500)
    ap.add_argument("--scene", default="crates")
    ap.add_argument("--share", type=float, default=SORT_SHARE, help="the sorted map's sort_share")
    args = ap.parse_args()
    if args.frames < 2:
        ap.error(f"--frames must be at least 2 (frame 1 is tracked from frame 0), got {args.frames}")
    print(f"load average {load()} on {os.cpu_count()} cores (the machine is shared: timings are noisy)")
    seq = render_once(args.scene, args.frames)
    warm_dense()   # the kernels loaded (or compiled) before anything is timed
    sorts = []
    original = fusion.PointMap.sort_spatially

    def timed_sort(pmap):
        start = time.perf_counter()
        original(pmap)
        sorts.append(time.perf_counter() - start)

    fusion.PointMap.sort_spatially = timed_sort
    cfg = fusion.FusionConfig()
    maps = {"unsorted": fusion.PointMap(), "sorted": fusion.PointMap()}
    maps["unsorted"].sort_share, maps["sorted"].sort_share = None, args.share
    splat = Splatter(seq.K, cfg.d_thr)
    spent = {name: [] for name in maps}
    visited = {name: [] for name in maps}
    size = []
    for k in range(args.frames):
        frame = seq.frame(k)
        for name in sorted(maps, reverse=bool(k % 2)):
            pmap, start = maps[name], time.perf_counter()
            if k:
                visited[name].append(view_source(pmap, splat, seq.rotations[k - 1], seq.positions[k - 1]).visited)
            fusion.fuse(pmap, frame, seq.rotations[k], seq.positions[k], k, cfg)
            spent[name].append(time.perf_counter() - start)
        size.append(len(maps["sorted"]))
    rows = []
    for lo in range(0, args.frames, 100):
        part = slice(lo, lo + 100)
        ms = {name: 1000 * float(np.median(spent[name][part])) for name in maps}
        kilo = {name: np.median(visited[name][max(lo - 1, 0):lo + 99]) / 1000 for name in maps}
        rows.append([f"{lo}-{min(lo + 100, args.frames) - 1}", f"{np.median(size[part]) / 1000:.0f}k",
                     ms["unsorted"], ms["sorted"], f"{kilo['unsorted']:.0f}k", f"{kilo['sorted']:.0f}k"])
    print_table(["frames", "map points", "splat + fusion unsorted (ms)", "sorted (ms)", "splat visited unsorted",
                 "sorted"], rows)
    print(f"{len(sorts)} sorts, {1000 * sum(sorts):.0f} ms in all ({1000 * min(sorts):.1f}-{1000 * max(sorts):.1f} ms "
          f"each); whole run: unsorted {sum(spent['unsorted']):.2f} s, sorted {sum(spent['sorted']):.2f} s; load after "
          f"{load()}")


if __name__ == "__main__":
    run_recorded(main)
