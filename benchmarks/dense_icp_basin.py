"""ICP's capture range on the shipped dense scenes: frame 10 against frame 10 + d, from the
identity start (the homework's frames 10 -> 50 and 10 -> 100 experiment), over seeds.

Each seed is a different run of the scene's dense path (start phase and jitter) and of the
sensor's noise. Source: frame 10's measured points at its true pose; target: frame 10 + d;
initial guess: frame 10's pose (the relative pose is the identity). ICP with the defaults
(``IcpConfig()``, projective association). An estimate is "right" within 1 mm / 0.1 deg of the
true pose (the issue's tolerance), "close" within 1 cm / 0.5 deg (the sensor's noise limits one
pair of frames to about a millimetre), else "wrong".

Columns per (scene, d): the true motion (median over seeds), then counts over seeds: right and
accepted, close and accepted, right or close but rejected, wrong and rejected, wrong and ACCEPTED
(a wrong pose reported as good: must be 0), the worst error of an accepted pose, and the
rejection reasons seen.

Usage: python benchmarks/dense_icp_basin.py [--seeds 4] [--noise-free]   (about 1 min a scene)
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dense_synthetic import pose_error  # noqa: E402

from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.tracks.dense.icp import icp  # noqa: E402
from assocbench.tracks.dense.run import frame_source  # noqa: E402
from assocbench.tracks.dense.sequence import DenseSequenceSpec, load_dense_sequence  # noqa: E402
from assocbench.tracks.dense.settings import DepthConfig, IcpConfig
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402

GAPS = {"crates": (5, 20, 30, 40, 50, 60, 70, 90, 130), "bays": (1, 2, 4, 6, 10, 20, 40, 90)}
SOURCE = 10


def outcomes(scene: str, seed: int, noise: bool) -> list[tuple]:
    """(d, motion m, motion deg, error m, error deg, failed, reason) per gap d."""
    depth = DepthConfig() if noise else DepthConfig(sigma_base=0.0, sigma_quad=0.0)
    seq = load_dense_sequence(DenseSequenceSpec(scene=scene, frames=SOURCE + max(GAPS[scene]) + 1, seed=seed,
                                                depth=depth))
    A = seq.frame(SOURCE)
    src = frame_source(A, A.R, A.t)
    out = []
    for d in GAPS[scene]:
        B = seq.frame(SOURCE + d)
        r = icp(src.points, src.normals, B, make_dense_associator("projective"), A.R, A.t, IcpConfig())
        out.append((d, *pose_error(A.R, A.t, B.R, B.t), *pose_error(r.R, r.t, B.R, B.t), r.failed,
                    r.reason.split(":")[0].split(" (")[0][:28]))
    return out


def rows(scene: str, seeds: int, noise: bool) -> list[list]:
    per_gap: dict[int, list[tuple]] = {}
    for seed in range(seeds):
        for o in outcomes(scene, seed, noise):
            per_gap.setdefault(o[0], []).append(o)
    table = []
    for d, os in per_gap.items():
        right = [o for o in os if o[3] < 1e-3 and o[4] < 0.1]
        close = [o for o in os if o[3] < 1e-2 and o[4] < 0.5 and o not in right]
        wrong = [o for o in os if o not in right and o not in close]
        accepted = [o for o in os if not o[5]]
        worst = max((1000 * o[3] for o in accepted), default=float("nan"))
        reasons = Counter(o[6] for o in os if o[5])
        table.append([scene, SOURCE, SOURCE + d, round(1000 * float(np.median([o[1] for o in os]))),
                      round(float(np.median([o[2] for o in os])), 1), sum(not o[5] for o in right),
                      sum(not o[5] for o in close), sum(o[5] for o in right + close), sum(o[5] for o in wrong),
                      sum(not o[5] for o in wrong),
                      round(worst, 2), "; ".join(f"{k} x{v}" for k, v in reasons.items())])
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--noise-free", action="store_true", help="noise-free depth (default: the sensor's noise)")
    ap.add_argument("--scenes", default="crates,bays")
    args = ap.parse_args()
    warm_dense()
    table = [r for scene in args.scenes.split(",") for r in rows(scene, args.seeds, not args.noise_free)]
    print(f"ICP from the identity, frame {SOURCE} -> {SOURCE} + d, {args.seeds} seeds, "
          f"{'noise-free' if args.noise_free else 'sensor noise'}, IcpConfig() defaults")
    print_table(["scene", "from", "to", "motion mm", "motion deg", "right ok", "close ok",
                 "right/close rejected", "wrong rejected", "WRONG ACCEPTED", "worst accepted mm", "reasons"], table)


if __name__ == "__main__":
    run_recorded(main)
