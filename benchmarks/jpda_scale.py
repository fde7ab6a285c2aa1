"""JPDA against n on range-bearing problems (EKF-SLAM-like: detection 0.8, clutter 20 % of n),
with MNN in the same process as the baseline; and the calibration of ``max_events``.

Rows: ``jpda`` (shipped parameters), ``jpda-bp`` (``max_events=1``: loopy BP on every cluster,
to show what the approximation costs in accuracy) and ``mnn``.

Scale table, per n (``--problems`` problems each): median and p95 ms of ``associate`` (best of 3
calls per problem, one core), precision, recall, mean true mass (``scoring.metrics.true_mass``;
for MNN its hard answer as one-hot marginals), the share of problems JPDA solved exactly (every
cluster enumerated), the median and largest number of joint events enumerated per problem,
approximate (BP) clusters over all problems and the largest cluster (landmarks).

Calibration: exact JPDA on single clusters of 10 landmarks and 12 features with random gating,
dense enough for 10^3..10^6 events: ms per call and ns per event, so ``max_events`` can be read
off for a time budget (the default keeps exact JPDA at n = 10 within 5 ms).

Usage: python benchmarks/jpda_scale.py [--problems 20] [--sizes 10 20 40 80 160 320] [--no-calibration]
"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import make_associator
from assocbench.associators.jpda import BP_MAX_SWEEPS, BP_TOL, JPDA
from assocbench.associators.jpda_kernels import jpda_marginals
from assocbench.models.synthetic import range_bearing_problem
from assocbench.scoring.metrics import true_mass


def one_hot(association: np.ndarray, m: int) -> np.ndarray:
    """A hard answer as marginals (n, m + 1): all mass on the chosen feature or on 'unassociated'."""
    out = np.zeros((len(association), m + 1))
    out[np.arange(len(association)), np.where(association >= 0, association, m)] = 1.0
    return out


def scale_rows(sizes: list[int], problems: int) -> list[list[object]]:
    rows = []
    for n in sizes:
        batch = [range_bearing_problem(np.random.default_rng(1000 * n + s), n=n) for s in range(problems)]
        for method, assoc in (("jpda", make_associator("jpda")), ("jpda-bp", make_associator("jpda", max_events=1)),
                              ("mnn", make_associator("mnn"))):
            times, tp, fp, fn, mass, exact, events, approx, largest = [], 0, 0, 0, [], 0, [], 0, 0
            for problem, truth in batch:
                out = assoc.associate(problem)   # warm-up and accuracy
                tp += int(np.sum((out >= 0) & (out == truth)))
                fp += int(np.sum((out >= 0) & (out != truth)))
                fn += int(np.sum((truth >= 0) & (out != truth)))
                info = assoc.info if assoc.soft else {"marginals": one_hot(out, problem.m)}
                mass.append(true_mass(info["marginals"], truth))
                if assoc.soft:
                    exact += int(info["exact"])
                    events.append(info["events"])
                    approx += info["approximate_clusters"]
                    largest = max(largest, info["largest_cluster"])
                times.append(time_call(lambda: assoc.associate(problem), 3))
            soft = [f"{exact / problems:.2f}", int(np.median(events)), max(events), approx, largest] if events \
                else ["-"] * 5
            rows.append([method, n, *summary_ms(times), tp / max(tp + fp, 1), tp / max(tp + fn, 1),
                         float(np.mean(mass)), *soft])
    return rows


def calibration_rows(max_events: int) -> list[list[object]]:
    """Exact enumeration cost on 10-landmark clusters (random gating, log-weights N(0, 1))."""
    rng = np.random.default_rng(7)
    rows = []
    for density in (0.15, 0.2, 0.25, 0.3, 0.35, 0.4):
        for _ in range(3):
            gated = rng.uniform(size=(12, 10)) < density
            logr = rng.normal(size=(12, 10))
            _, events, clusters, _, largest, _ = jpda_marginals(gated, logr, 10**9, BP_TOL, BP_MAX_SWEEPS)
            if clusters != 1 or largest != 10:
                continue
            seconds = time_call(lambda: jpda_marginals(gated, logr, 10**9, BP_TOL, BP_MAX_SWEEPS), 5)
            rows.append([density, events, seconds * 1e3, seconds * 1e9 / events])
    rows.sort(key=lambda r: r[1])
    worst = max(r[3] for r in rows)
    rows.append(["at max_events", max_events, max_events * worst * 1e-6, worst])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    ap.add_argument("--no-calibration", action="store_true")
    args = ap.parse_args()
    if not args.no_calibration:
        print("calibration: exact JPDA on one cluster of 10 landmarks x 12 features (worst ns/event at max_events)")
        print_table(["gate density", "events", "ms", "ns/event"], calibration_rows(JPDA().max_events))
    print(f"range-bearing, {args.problems} problems per n (p_detect 0.8, clutter 0.2 n); JPDA shipped parameters")
    print_table(["method", "n", "median ms", "p95 ms", "precision", "recall", "true mass", "exact share",
                 "events median", "events max", "BP clusters", "largest cluster"], scale_rows(args.sizes, args.problems))


if __name__ == "__main__":
    run_recorded(main)
