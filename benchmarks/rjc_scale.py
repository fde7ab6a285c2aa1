"""RJC against JCBB as n grows: runtime (median and p95 of the best of 3 calls per problem),
precision and recall against the truth, and pairings, on range-bearing problems (80 % detection,
clutter 20 % of n, full correlated covariance); JCBB (its default node budget) runs in the same
process as the baseline, timed once per problem. One core.

Usage: python benchmarks/rjc_scale.py [--problems 20] [--sizes 10 20 40 80 160 320]
       [--params sample_size=2 ...] [--hard]
"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import make_associator
from assocbench.models.synthetic import range_bearing_problem


def scores(out: np.ndarray, truth: np.ndarray) -> tuple[int, int, int, int]:
    """(true pairings, false pairings, pairings, true pairs that exist)."""
    paired = out >= 0
    return int(np.sum(paired & (out == truth))), int(np.sum(paired & (out != truth))), int(paired.sum()), \
        int(np.sum(truth >= 0))


def measure(method: str, params: dict, batch: list, repeat: int) -> dict:
    """Times, accuracy and ``info`` totals of one method over a batch of (problem, truth)."""
    assoc = make_associator(method, **params)
    assoc.associate(batch[0][0])                          # load the compiled kernels
    times, totals, timed_out, iterations = [], np.zeros(4, int), 0, []
    for problem, truth in batch:
        out = assoc.associate(problem)
        totals += scores(out, truth)
        timed_out += int(assoc.info.get("timed_out", False))
        iterations.append(assoc.info.get("iterations", 0))
        times.append(time_call(lambda: assoc.associate(problem), repeat))
    tp, fp, pairs, real = totals
    return {"ms": summary_ms(times), "precision": tp / max(tp + fp, 1), "recall": tp / max(real, 1),
            "pairs": int(pairs), "timed_out": timed_out, "iterations": float(np.mean(iterations))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    ap.add_argument("--params", nargs="*", default=[], metavar="KEY=VALUE", help="RJC parameters (numbers)")
    ap.add_argument("--hard", action="store_true", help="pose σ 1 m and 8°, landmarks within 10 m")
    args = ap.parse_args()
    params = {k: (float(v) if "." in v else int(v)) for k, v in (p.split("=", 1) for p in args.params)}
    model = dict(sigma_pose=(1.0, np.deg2rad(8.0)), extent=10.0) if args.hard else {}
    rows = []
    for n in args.sizes:
        batch = [range_bearing_problem(np.random.default_rng(1000 * n + s), n=n, **model) for s in range(args.problems)]
        r = measure("rjc", params, batch, repeat=3)
        j = measure("jcbb", {}, batch, repeat=1)
        rows.append([n, *r["ms"], r["iterations"], r["precision"], r["recall"], r["pairs"],
                     j["ms"][0], j["timed_out"], j["precision"], j["recall"], j["pairs"]])
    print(f"RJC {params or '(shipped parameters)'} vs JCBB, range-bearing{' (hard)' if args.hard else ''}, "
          f"{args.problems} problems per n; ms per problem; pairings summed over the problems")
    print_table(["n", "rjc med", "rjc p95", "iters", "rjc prec", "rjc rec", "rjc pairs",
                 "jcbb med", "jcbb t/o", "jcbb prec", "jcbb rec", "jcbb pairs"], rows)


if __name__ == "__main__":
    run_recorded(main)
