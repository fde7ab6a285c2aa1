"""CCDA against JCBB as n grows: range-bearing problems (EKF-SLAM-like, landmarks correlated with
the pose; detection 0.8, clutter 20 % of n), the same problems for both methods, in one process.
Per n: median and p95 runtime (best of --repeat calls per problem), precision and recall of
the pairings against the truth, and the share of problems solved to proven optimality (CCDA:
the clique is maximum; JCBB: the search ended within its node budget). A second table runs
CCDA without the unary gate (``unary=False``: every pair a vertex, no pose prior used).

Usage: python benchmarks/ccda_scale.py [--problems 20] [--sizes 10 20 40 80 160 320]
       [--free-sizes 10 20 40] [--repeat 3]
"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import make_associator
from assocbench.models.synthetic import range_bearing_problem


def proven(assoc) -> bool:
    info = getattr(assoc, "info", {})
    return bool(info.get("proven_optimal", not info.get("timed_out", False)))


def measure(assoc, batch, repeat: int) -> list:
    """[median ms, p95 ms, precision, recall, share proven optimal] over the batch."""
    times, tp, fp, positives, optimal = [], 0, 0, 0, 0
    for problem, truth in batch:
        out = assoc.associate(problem)              # warm-up, accuracy and the search's verdict
        optimal += proven(assoc)
        tp += int(np.sum((out >= 0) & (out == truth)))
        fp += int(np.sum((out >= 0) & (out != truth)))
        positives += int(np.sum(truth >= 0))
        times.append(time_call(lambda: assoc.associate(problem), repeat))
    med, p95 = summary_ms(times)
    return [med, p95, tp / max(tp + fp, 1), tp / max(positives, 1), optimal / len(batch)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    ap.add_argument("--free-sizes", type=int, nargs="*", default=[10, 20, 40])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    batches = {n: [range_bearing_problem(np.random.default_rng(1000 * n + s), n=n) for s in range(args.problems)]
               for n in sorted(set(args.sizes) | set(args.free_sizes))}
    ccda, jcbb = make_associator("ccda"), make_associator("jcbb")
    rows = []
    for n in args.sizes:
        rows.append([n, *measure(ccda, batches[n], args.repeat), *measure(jcbb, batches[n], args.repeat)])
    print(f"CCDA vs JCBB, range-bearing, {args.problems} problems per n, ms per problem "
          f"(defaults: ccda max_nodes={ccda.max_nodes}, jcbb max_nodes={jcbb.max_nodes})")
    print_table(["n", "ccda med", "ccda p95", "ccda prec", "ccda rec", "ccda optimal",
                 "jcbb med", "jcbb p95", "jcbb prec", "jcbb rec", "jcbb optimal"], rows)
    if args.free_sizes:
        free = make_associator("ccda", unary=False)
        rows = [[n, *measure(free, batches[n], 1)] for n in args.free_sizes]
        print("CCDA with unary=False (no individual gate: every pair a vertex), best of 1 call")
        print_table(["n", "med", "p95", "precision", "recall", "optimal"], rows)


if __name__ == "__main__":
    run_recorded(main)
