"""Projective against KD-tree dense association on the same frames: precision, recall, pairs and time.

Frames: the dense track's sequences of ``crates`` and ``bays`` (320x240, the dense paths over 200
frames), with the sensor's default noise and noise-free (same renders, same grazing dropouts and
normal smoothing, ``sigma_base = sigma_quad = 0``). For ``--frames`` frames k (every ``--stride``-th
along the path from 0) the target is frame k+1 and the source is either

- frame-to-frame: frame k's valid pixels placed at its TRUE pose (``tracks.dense.run.frame_source``), or
- frame-to-model: the map fused over frames 0..k at their true poses (``point_fusion.fuse``,
  default ``FusionConfig``), which grows along the path: the KD-tree's cost on a big map.

Each method associates the source with frame k+1 from a guess of its pose: the true pose, or the
true pose turned 1 deg / moved 2 cm, or 3 deg / 5 cm (random axis and direction, seeded per frame;
both methods get the same guess). Default filters (``d_thr`` 5 cm, 30 deg). Pairs are scored
against per-pixel truth as the harness does (``score_correspondences``, ``dense.truth_tol`` = 3 cm:
a true pair lies on one geom with true positions within 3 cm; recall counts the source points that
have a true partner pixel).

Columns (means over the frames): precision, recall, pairs per frame; source points; median ms of
one ``associate()`` call (median over ``--runs`` calls per frame, then over frames; for the
KD-tree the tree is already built) and, for the KD-tree, the median ms of building the frame's
tree (once per frame, shared by all ICP iterations on it). A second table gives, for
frame-to-model from the true pose, each frame's map size, the map points in the frustum
(``considered``) and both methods' ms.

Usage: python benchmarks/dense_association.py [--frames 10] [--stride 18] [--runs 5]
(renders 2 x 164 frames into the cache on the first run, ~10 s; then about 3 min on one core)
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms, timed

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dense_synthetic import perturb  # noqa: E402

from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.tracks.dense.fusion import PointMap, fuse, warm_fusion  # noqa: E402
from assocbench.tracks.dense.metrics import score_correspondences  # noqa: E402
from assocbench.tracks.dense.run import Source, frame_source, map_source  # noqa: E402
from assocbench.tracks.dense.sequence import DenseSequenceSpec, load_dense_sequence  # noqa: E402
from assocbench.tracks.dense.settings import DenseConfig, DepthConfig, FusionConfig
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402

SCENES = ("crates", "bays")
NOISE = {"default noise": DepthConfig(), "noise-free": DepthConfig(sigma_base=0.0, sigma_quad=0.0)}
STARTS = (("true pose", 0.0, 0.0), ("1 deg / 2 cm", 1.0, 0.02), ("3 deg / 5 cm", 3.0, 0.05))
METHODS = ("projective", "kdtree")
TOL = DenseConfig().truth_tol


@dataclass
class Cell:
    """Per-frame figures of one (scene, noise, source, start, method)."""

    precision: list = field(default_factory=list)
    recall: list = field(default_factory=list)
    pairs: list = field(default_factory=list)
    sources: list = field(default_factory=list)
    ms: list = field(default_factory=list)
    considered: list = field(default_factory=list)


def median_ms(fn, runs: int) -> float:
    """Median wall time of ``runs`` calls of ``fn``, ms (one untimed call first)."""
    return summary_ms(timed(fn, runs, 1))[0]


def tree_build_ms(kd, frame, runs: int) -> float:
    """Median ms of building ``frame``'s KD-tree (the cache cleared before each build)."""
    def build():
        kd._cache = None
        kd.tree(frame)
    return median_ms(build, runs)


def associate_all(cells: dict, key: tuple, source: Source, frame, k: int, seed: int, runs: int,
                  associators: dict) -> None:
    """Both methods from each start guess of ``frame``'s pose; figures appended to ``cells``."""
    for level, (start, deg, trans) in enumerate(STARTS):
        R0, t0 = perturb(frame.R, frame.t, deg, trans, np.random.default_rng([seed, k, level]))
        for method, assoc in associators.items():
            pairs = assoc.associate(source.points, source.normals, frame, R0, t0)
            score = score_correspondences(source.true_points, source.geom, frame, pairs.source, pairs.pixel, TOL)
            cell = cells.setdefault((*key, start, method), Cell())
            cell.precision.append(score.precision)
            cell.recall.append(score.recall)
            cell.pairs.append(len(pairs))
            cell.sources.append(len(source.points))
            cell.considered.append(pairs.considered)
            cell.ms.append(median_ms(lambda: assoc.associate(source.points, source.normals, frame, R0, t0), runs))


def run_scene(scene: str, noise: str, args, cells: dict, builds: dict) -> None:
    """Frame-to-frame and frame-to-model association of ``--frames`` frames of one sequence."""
    ks = [i * args.stride for i in range(args.frames)]
    seq = load_dense_sequence(DenseSequenceSpec(scene=scene, frames=ks[-1] + 2, depth=NOISE[noise],
                                                seed=args.seed))
    associators = {m: make_dense_associator(m) for m in METHODS}
    pmap, fused, cfg = PointMap(), 0, FusionConfig()
    previous = None
    for k in ks:
        while fused <= k:   # the map holds frames 0..k, fused at their true poses
            previous = seq.frame(fused)
            fuse(pmap, previous, previous.R, previous.t, fused, cfg)
            fused += 1
        target = seq.frame(k + 1)
        builds.setdefault((scene, noise), []).append(tree_build_ms(associators["kdtree"], target, args.runs))
        associate_all(cells, (scene, noise, "frame"), frame_source(previous, previous.R, previous.t), target, k,
                      args.seed, args.runs, associators)
        associate_all(cells, (scene, noise, "model"), map_source(pmap), target, k, args.seed, args.runs,
                      associators)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=10, help="frame pairs (k, k+1) per scene")
    ap.add_argument("--stride", type=int, default=18, help="k = 0, stride, 2 stride, ... along the path")
    ap.add_argument("--runs", type=int, default=5, help="timed associate() calls per frame and method")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    warm_dense()
    warm_fusion()
    cells, builds = {}, {}
    for noise in NOISE:
        for scene in SCENES:
            run_scene(scene, noise, args, cells, builds)
    print(f"dense association, {args.frames} frames k = 0, {args.stride}, ... per scene (target k+1); "
          f"truth tol {TOL * 100:.0f} cm; ms: median of {args.runs} calls, median over frames")
    for source in ("frame", "model"):
        rows = []
        for (scene, noise, src, start, method), c in cells.items():
            if src != source:
                continue
            build = float(np.median(builds[scene, noise])) if method == "kdtree" else "-"
            rows.append([scene, noise, start, method, float(np.nanmean(c.precision)), float(np.nanmean(c.recall)),
                         round(float(np.mean(c.pairs))), round(float(np.mean(c.sources))),
                         float(np.median(c.ms)), build])
        print("frame-to-frame (source: frame k at its true pose)" if source == "frame"
              else "frame-to-model (source: the map fused over frames 0..k at true poses)")
        print_table(["scene", "noise", "start", "method", "precision", "recall", "pairs", "source pts", "ms",
                     "tree build ms"], rows)
    rows = []
    for scene in SCENES:
        noise = next(iter(NOISE))
        proj, kd = (cells[scene, noise, "model", STARTS[0][0], m] for m in METHODS)
        for i in range(args.frames):
            rows.append([scene, i * args.stride, kd.sources[i], kd.considered[i], proj.ms[i], kd.ms[i],
                         builds[scene, noise][i]])
    print("frame-to-model from the true pose, default noise, per frame: the KD-tree's cost against map size")
    print_table(["scene", "k", "map points", "kdtree considered", "projective ms", "kdtree ms", "tree build ms"],
                rows)


if __name__ == "__main__":
    run_recorded(main)
