"""Associator runtime against the number of candidates n, for two measurement models:
range-bearing (EKF-SLAM-like, landmarks correlated with the pose) and camera pixels (the
rendered benchmark's belief model). Detection probability 0.8, clutter 20 % of n, full
correlated covariance; median and p95 over the problems; one core.

Usage: python benchmarks/associator_runtime.py [--problems 20] [--sizes 10 20 40 80 160 320]
       [--png benchmarks/associator_runtime.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import make_associator
from assocbench.associators.registry import geometric_builtins
from assocbench.models.synthetic import range_bearing_problem
from assocbench.tracks.camera.synthetic import camera_problem

MODELS = {"range-bearing": range_bearing_problem, "camera": camera_problem}


def measure(model: str, sizes: list[int], problems: int, methods: list[str]) -> dict:
    results = {}
    for n in sizes:
        batch = [MODELS[model](np.random.default_rng(1000 * n + s), n=n) for s in range(problems)]
        for method in methods:
            assoc = make_associator(method)
            times, timeouts, tp, fp, fn = [], 0, 0, 0, 0
            for problem, truth in batch:
                out = assoc.associate(problem)   # warm-up and accuracy
                timeouts += int(getattr(assoc, "info", {}).get("timed_out", False))
                tp += int(np.sum((out >= 0) & (out == truth)))
                fp += int(np.sum((out >= 0) & (out != truth)))
                fn += int(np.sum((truth >= 0) & (out != truth)))
                times.append(time_call(lambda: assoc.associate(problem), 3))
            results[(method, n)] = (*summary_ms(times), timeouts, tp / max(tp + fp, 1), tp / max(tp + fn, 1))
    return results


def plot(all_results: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(all_results), figsize=(6 * len(all_results), 4.2), squeeze=False)
    for ax, (model, res) in zip(axes.flat, all_results.items()):
        methods = sorted({m for m, _ in res})
        for k, method in enumerate(methods):
            ns = sorted(n for m, n in res if m == method)
            ax.plot(ns, [res[(method, n)][0] for n in ns], "o-", color=f"C{k}", label=method)
        ax.set(xscale="log", yscale="log", xlabel="candidates n", ylabel="median ms per problem", title=model)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    ap.add_argument("--methods", nargs="+", default=geometric_builtins())
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    ap.add_argument("--png", default=str(Path(__file__).with_suffix(".png")))
    args = ap.parse_args()
    all_results = {}
    for model in args.models:
        res = measure(model, args.sizes, args.problems, args.methods)
        all_results[model] = res
        rows = [[m, n, *res[(m, n)]] for m in args.methods for n in args.sizes]
        print(f"{model}: ms per problem over {args.problems} problems (p_detect 0.8, clutter 0.2 n)")
        print_table(["method", "n", "median ms", "p95 ms", "timed out", "precision", "recall"], rows)
    plot(all_results, args.png)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    run_recorded(main)
