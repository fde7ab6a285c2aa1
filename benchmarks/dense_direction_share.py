"""Evidence for ICP's ``min_direction_share``: its direction share (and inlier share, κ) on the
steps ICP got right and on those it accepted wrong, with the test switched off.

Each run is the dense track's own frame loop (``assocbench run --method projective --scene S
--frames N --seed K --set dense.tracking=T``, the leaderboard's settings) with
``icp.min_direction_share = 0``, so that no step is rejected for a lost direction and the
statistics of the wrong steps the test exists to catch are seen. A step is wrong when its
estimate is more than 20 mm from the true step (the leaderboard's ``wrong_steps``). Per run:
right and wrong steps, the direction share's range over each, the inlier share and κ of the
wrong ones, and how many of each the default ``min_direction_share`` would reject.

Usage: python benchmarks/dense_direction_share.py [--frames 40] [--seeds 0 1] [--scenes bays crates]
(about 10 s a run of 40 frames on a quiet core, after the kernels are compiled)
"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded

from assocbench.associators.registry import make_dense_associator
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.runner import GuardedCalls
from assocbench.tracks.dense.run import dense_records
from assocbench.tracks.dense.settings import IcpConfig
from assocbench.tracks.dense.track import gate_params
from assocbench.tracks.dense.warm import warm_dense

WRONG_MM = 20.0   # the leaderboard's wrong step


def records(scene: str, seed: int, tracking: str, frames: int) -> list[dict]:
    """The per-frame records of one run with the direction test off."""
    cfg = load_run_config(None, [f"dense.tracking={tracking}", "dense.path_frames=200", "icp.min_direction_share=0"],
                          method="projective", scene=scene, frames=frames, seed=seed)
    spec = run_spec(cfg)
    seq = spec.source.sequence
    calls = GuardedCalls(spec.time_limit_s, {}, lambda k, limit: None)
    return list(dense_records(seq, spec, calls, lambda: make_dense_associator(spec.method, **gate_params(spec))))


def span(values: list[float]) -> str:
    return f"{min(values):.3f}-{max(values):.3f}" if values else "-"


def row(scene: str, seed: int, tracking: str, frames: int, threshold: float) -> list:
    recs = [r for r in records(scene, seed, tracking, frames)[1:] if not r["icp_failed"]]
    right = [r for r in recs if r["step_error_mm"] <= WRONG_MM]
    wrong = [r for r in recs if r["step_error_mm"] > WRONG_MM]
    share = [r["direction_share"] for r in right]
    return [f"{scene} s{seed} {tracking}", len(right), len(wrong), span(share),
            f"{np.percentile(share, 5):.3f}" if share else "-", span([r["direction_share"] for r in wrong]),
            span([r["inlier_share"] for r in wrong]), sum(r["direction_share"] < threshold for r in right),
            sum(r["direction_share"] < threshold for r in wrong)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--scenes", nargs="+", default=["bays", "crates"])
    args = ap.parse_args()
    warm_dense()
    threshold = IcpConfig().min_direction_share
    table = [row(scene, seed, tracking, args.frames, threshold) for scene in args.scenes for seed in args.seeds
             for tracking in ("model", "frame")]
    print(f"projective ICP, {args.frames} frames, accepted steps with icp.min_direction_share = 0; "
          f"wrong: > {WRONG_MM:.0f} mm from the true step; default min_direction_share {threshold}")
    print_table(["run", "right", "wrong", "dir. share right", "right p5", "dir. share wrong", "inlier share wrong",
                 "right rejected", "wrong rejected"], table)


if __name__ == "__main__":
    run_recorded(main)
