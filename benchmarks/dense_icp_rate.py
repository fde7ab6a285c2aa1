"""Projective association and point-to-plane ICP at 320x240 on one core: the dense track's inner loop.

Frames: the synthetic room corner with a crate (tests/dense_synthetic.py), noise-free; the
source is every valid pixel of the frame at pose A (~76 000 points, world coordinates), the
target the frame at B = A moved 2 deg / 5 cm, the pose guess B perturbed by 1 deg / 1 cm.

Rows: median and p95 milliseconds over ``--runs`` timed calls (after ``--warmup`` untimed ones),
and the ratio of the median to the baseline, a plain-numpy projective association
(``projective.associate_numpy``, the same computation) timed in the same process.
"build + solve" is the 6x6 normal equations in one compiled pass plus the damped eigen-solve;
"one ICP iteration" is ``icp`` with ``max_iterations=1`` (association + build + solve + update;
target <= 3 ms); "ICP to convergence" is the whole call from the guess.

Usage: python benchmarks/dense_icp_rate.py [--runs 50] [--warmup 5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms, timed

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dense_synthetic import ROOM, perturb, render, room_frame, source_set  # noqa: E402

from assocbench.associators.dense.projective import associate_numpy  # noqa: E402
from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.tracks.dense.icp import icp, normal_equations, solve_update, stability_transform  # noqa: E402
from assocbench.tracks.dense.settings import IcpConfig
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    warm_dense()
    A = room_frame()
    RB, tB = perturb(A.R, A.t, 2.0, 0.05, np.random.default_rng(7))
    B = render(ROOM, RB, tB)
    pts, nrm, *_ = source_set(A)
    R0, t0 = perturb(RB, tB, 1.0, 0.01, np.random.default_rng(3))
    TR, Tt = R0.T.copy(), -R0.T @ t0
    proj, kd = make_dense_associator("projective"), make_dense_associator("kdtree")
    pairs = proj.associate(pts, nrm, B, R0, t0)

    def build_solve():
        H, g, _, sp, spp = normal_equations(pts, B, pairs, TR, Tt)
        return solve_update(H, g, stability_transform(sp, spp, len(pairs)))

    def kd_build():
        kd._cache = None
        kd.tree(B)

    one = IcpConfig(max_iterations=1)
    cases = [
        ("projective, plain numpy (baseline)", lambda: associate_numpy(pts, nrm, B, R0, t0)),
        ("projective association", lambda: proj.associate(pts, nrm, B, R0, t0)),
        ("kdtree: tree build (once per frame)", kd_build),
        ("kdtree association (query)", lambda: kd.associate(pts, nrm, B, R0, t0)),
        ("build 6x6 system", lambda: normal_equations(pts, B, pairs, TR, Tt)),
        ("build + solve", build_solve),
        ("one ICP iteration, projective", lambda: icp(pts, nrm, B, proj, R0, t0, one)),
        ("one ICP iteration, kdtree", lambda: icp(pts, nrm, B, kd, R0, t0, one)),
        ("ICP to convergence, projective", lambda: icp(pts, nrm, B, proj, R0, t0)),
    ]
    kd.tree(B)
    rows, base = [], None
    for label, fn in cases:
        med, p95 = summary_ms(timed(fn, args.runs, args.warmup))
        base = med if base is None else base
        rows.append([label, med, p95, f"{med / base:.3f}"])
    res = icp(pts, nrm, B, proj, R0, t0)
    print(f"dense ICP inner loop, {len(pts)} source points against a {B.K.width}x{B.K.height} frame, "
          f"{len(pairs)} pairs; {args.runs} runs (median, p95); full ICP: {res.iterations} iterations, "
          f"converged={res.converged}")
    print_table(["step", "median ms", "p95 ms", "x numpy baseline"], rows)


if __name__ == "__main__":
    run_recorded(main)
