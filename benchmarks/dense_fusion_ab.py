"""Two versions of the dense track's fusion timed against each other on the same frames: the A/B
for a change that must keep the maps bit for bit (a data layout, a loop order).

What it runs. ``--pairs`` rounds; in each, one process per source tree, alternating, so that a
machine that slows down or speeds up during the run (a shared one does) weighs on both alike.
Each process fuses the first ``--frames`` frames of the crates circle (``dense_rate.py``'s path
and settings: 320x240, the default path's speed) at their true poses with ``FusionConfig()``
and times ``fuse`` and its three kernels, the merge pass (``_merge_pass``: the map points in
view), the cell pass (``_add_pass``: the pixels no point merged with) and the samples' merge
(``_apply_samples``), over frames ``--from`` .. ``--frames`` − 1 (the first frames, untimed,
build the map and compile). Columns: ms a frame, the median over the rounds of each process's
mean; the map's points at the end; the hash of its positions, normals and weights (one hash for
both trees: the same map bit for bit). A tree is a checkout of this repository, e.g.
``git worktree add /tmp/before HEAD~1``; each keeps numba's cache beside its own sources. The
frames come from this script's ``dense_rate.py`` run on each tree's ``assocbench``, so a tree
older than what ``dense_rate.py`` imports fails, in one line naming its error.

Usage: python benchmarks/dense_fusion_ab.py BEFORE AFTER [--pairs 13] [--frames 300] [--from 150]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

KERNELS = ("_merge_pass", "_add_pass", "_apply_samples")
LABELS = ("merge pass", "cell pass", "samples' merge")


def measure(frames: int, first: int) -> dict:
    """In a child process whose ``assocbench`` is one tree's: fuse and time (see the docstring)."""
    from dense_rate import render_once  # this script's folder: it is sys.path[0]

    import assocbench.tracks.dense.fusion as fusion

    seq, spent = render_once("crates", frames), dict.fromkeys(("fuse", *KERNELS), 0.0)

    def timed(name, fn):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[name] += time.perf_counter() - start
        return call

    for name in KERNELS:   # fuse calls them as module globals
        setattr(fusion, name, timed(name, getattr(fusion, name)))
    fuse, pmap = timed("fuse", fusion.fuse), fusion.PointMap()
    for k in range(frames):
        if k == first:
            spent.update(dict.fromkeys(spent, 0.0))
        fuse(pmap, seq.frame(k), seq.rotations[k], seq.positions[k], k, fusion.FusionConfig())
    digest = hashlib.sha1(b"".join(np.ascontiguousarray(a).tobytes()
                                   for a in (pmap.positions, pmap.normals, pmap.weights))).hexdigest()[:12]
    return {"ms": {name: 1000 * s / (frames - first) for name, s in spent.items()}, "points": len(pmap),
            "hash": digest}


def child(tree: Path, frames: int, first: int) -> dict:
    """``measure`` in a fresh process importing ``tree``'s assocbench."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    out = subprocess.run([sys.executable, __file__, "--child", str(frames), str(first)], env=env, cwd=tree,
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"dense_fusion_ab.py: the run in {tree} failed: {(out.stderr.strip().splitlines() or ['?'])[-1]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def tree_of(path: str) -> Path:
    """A source tree given on the command line, checked: it must hold the dense track's fusion."""
    tree = Path(path).resolve()
    if not (tree / "assocbench" / "tracks" / "dense" / "fusion.py").is_file():
        raise ValueError(f"{path}: not a checkout of assocbench (no assocbench/tracks/dense/fusion.py); "
                         f"make one with `git worktree add DIR COMMIT`")
    return tree


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        print(json.dumps(measure(int(sys.argv[2]), int(sys.argv[3]))))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trees", nargs=2, metavar="TREE", help="two checkouts of assocbench: before, after")
    ap.add_argument("--pairs", type=int, default=13, help="rounds, each one process per tree")
    ap.add_argument("--frames", type=int, default=300, help="crates frames fused")
    ap.add_argument("--from", dest="first", type=int, default=150, help="the first frame timed")
    args = ap.parse_args()
    if args.pairs < 1 or not 0 < args.first < args.frames:
        ap.error(f"need --pairs >= 1 and 0 < --from < --frames, got {args.pairs}, {args.first}, {args.frames}")
    try:
        trees = [tree_of(t) for t in args.trees]
    except ValueError as exc:
        ap.error(str(exc))
    runs = {tree: [] for tree in trees}
    for _ in range(args.pairs):
        for tree in trees:
            runs[tree].append(child(tree, args.frames, args.first))
    print(f"crates frames {args.first}-{args.frames - 1} fused at true poses, {args.pairs} alternating rounds; "
          f"ms a frame, the median over the rounds")
    rows = [[label, *(float(np.median([r["ms"][name] for r in runs[tree]])) for tree in trees)]
            for label, name in (("fuse", "fuse"), *zip(LABELS, KERNELS))]
    rows += [["map points", *(runs[tree][-1]["points"] for tree in trees)],
             ["map hash", *(",".join(sorted({r["hash"] for r in runs[tree]})) for tree in trees)]]
    print_table(["", f"before: {trees[0]}", f"after: {trees[1]}"], rows)
    same = {r["hash"] for rs in runs.values() for r in rs}
    print(f"the same map bit for bit: {'yes' if len(same) == 1 else 'no'}")


if __name__ == "__main__":
    run_recorded(main)
