"""The learned associator's runtime per frame against the number of candidates n, beside MNN's
(and LSA's, whose assignment it shares), on synthetic camera problems (``camera_problem``: the
rendered benchmark's belief model, detection 0.8, clutter 20 % of n); its time split into the
features, the trees and the assignment. Median and p95 over the problems (each the best of 3
calls); one core.

Usage: python benchmarks/learned_runtime.py [--problems 20] [--sizes 10 20 40 80 160]
"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import make_associator
from assocbench.associators.learned.associator import assign_log_odds
from assocbench.associators.learned.features import pair_features
from assocbench.tracks.camera.synthetic import camera_problem

METHODS = ("mnn", "lsa", "learned")


def stages(associator, problem) -> list[float]:
    """Best-of-3 seconds of the learned method's three stages on ``problem``."""
    forest = associator.forest_for(problem)
    feats, lms, X = pair_features(problem)
    odds = forest.log_odds(X)
    return [time_call(lambda: pair_features(problem), 3), time_call(lambda: forest.log_odds(X), 3),
            time_call(lambda: assign_log_odds(feats, lms, odds, forest.no_match, problem.m, problem.n), 3)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160])
    args = ap.parse_args()
    methods = {name: make_associator(name) for name in METHODS}
    rows = []
    for n in args.sizes:
        batch = [camera_problem(np.random.default_rng(1000 * n + s), n=n) for s in range(args.problems)]
        row = [n]
        for assoc in methods.values():
            f1_counts = np.zeros(3)
            times = []
            for problem, truth in batch:
                out = assoc.associate(problem)   # warm-up and accuracy
                f1_counts += [np.sum((out >= 0) & (out == truth)), np.sum((out >= 0) & (out != truth)),
                              np.sum((truth >= 0) & (out != truth))]
                times.append(time_call(lambda: assoc.associate(problem), 3))
            tp, fp, fn = f1_counts
            row += [*summary_ms(times), 2 * tp / max(2 * tp + fp + fn, 1)]
        split = np.median([stages(methods["learned"], p) for p, _ in batch], axis=0) * 1e3
        rows.append(row + list(split))
    headers = ["n"] + [f"{m} {c}" for m in METHODS for c in ("median ms", "p95 ms", "F1")]
    print_table(headers + ["learned: features ms", "trees ms", "assignment ms"], rows)


if __name__ == "__main__":
    run_recorded(main)
