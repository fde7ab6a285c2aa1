"""Anytime JCBB at scale: pairings against the classic first dive and against every known jointly
compatible hypothesis, proven-optimal share and time, with the default node budget.

Range-bearing EKF scans (pose-correlated landmarks, detection 0.8, clutter 20 % of n), 20+
problems per n. "Known" hypotheses: the true pairings that pass the individual gate, and every
other registered associator's answer, each counted only where all its pairings pass the
individual gate and the whole is jointly compatible, at the same confidence (JCBB's definition). A "short" problem is one where JCBB returns fewer pairings than any of them;
the target is none. The runtime is the median of 3 calls per problem, one core.

Usage: python benchmarks/jcbb_anytime.py [--problems 20] [--sizes 40 80 160 320]
       [--png benchmarks/jcbb_anytime.png]   (the anytime curves of the two issue-12 cases)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call

from assocbench import Problem, make_associator
from assocbench.association.compatibility import individually_compatible, jointly_compatible
from assocbench.association.problem import pairs_of
from assocbench.associators.jcbb import default_budget
from assocbench.associators.registry import geometric_builtins
from assocbench.models.synthetic import range_bearing_problem

CASES = Path(__file__).resolve().parents[1] / "tests" / "data"


def known_hypotheses(problem: Problem, truth: np.ndarray, others: dict) -> dict[str, int]:
    """Pairing counts of the jointly compatible hypotheses we know of, by source."""
    ic = individually_compatible(problem, 0.99)
    true_ic = np.where((truth >= 0) & ic[np.maximum(truth, 0), np.arange(problem.n)], truth, -1)
    found = {"truth": true_ic, **{name: assoc.associate(problem) for name, assoc in others.items()}}
    return {name: int(np.sum(a >= 0)) for name, a in found.items()
            if jointly_compatible(problem, a) and all(ic[i, j] for j, i in zip(*pairs_of(a)))}


def measure(n: int, problems: int) -> list:
    jcbb = make_associator("jcbb")
    others = {name: make_associator(name) for name in geometric_builtins() if name != "jcbb"}
    times, proven, over_dive, margin, short, best_source = [], 0, [], [], 0, {}
    for seed in range(problems):
        problem, truth = range_bearing_problem(np.random.default_rng(seed), n=n)
        out = jcbb.associate(problem)
        k = int(np.sum(out >= 0))
        proven += jcbb.info["proven_optimal"]
        dive = jcbb.info["dive_pairings"]          # None: the quick search proved it before any dive
        if dive is not None:
            over_dive.append(k - dive)
        known = known_hypotheses(problem, truth, others)
        source = max(known, key=known.get)
        best_source[source] = best_source.get(source, 0) + 1
        margin.append(k - known[source])
        short += int(k < known[source] or (dive is not None and k < dive))
        times.append(time_call(lambda: jcbb.associate(problem), 3))
    med, p95 = summary_ms(times)
    sources = ", ".join(f"{s} {c}" for s, c in sorted(best_source.items(), key=lambda kv: -kv[1]))
    dived = (min(over_dive), float(np.mean(over_dive))) if over_dive else ("-", "-")
    return [n, problems, med, p95, f"{proven}/{problems}", *dived, min(margin), short, sources]


def plot_cases(path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, name in zip(axes, ("jcbb_collapse_n80.npz", "jcbb_short_n160.npz")):
        d = np.load(CASES / name)
        problem = Problem(z=d["z"], R=d["R"], zhat=d["zhat"], P=d["P"], volume=float(d["volume"]),
                          angular=tuple(int(a) for a in d["angular"]))
        default = default_budget(int(individually_compatible(problem).any(axis=0).sum()))
        for budget in (default, 10 * default):
            jcbb = make_associator("jcbb", max_nodes=budget)
            jcbb.associate(problem)
            nodes, k, _ = zip(*jcbb.info["history"], (jcbb.info["nodes"], jcbb.info["history"][-1][1], 0))
            ax.step(nodes, k, where="post", label=f"max_nodes {budget}" + (" (default)" if budget == default else ""))
        ax.set(title=name, xlabel="nodes (dives and search)", ylabel="pairings of the incumbent", xscale="symlog")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[40, 80, 160, 320])
    ap.add_argument("--png", default=str(Path(__file__).with_suffix(".png")))
    args = ap.parse_args()
    rows = [measure(n, args.problems) for n in args.sizes]
    print("JCBB, default budget, range-bearing (p_detect 0.8, clutter 0.2 n); pairings: JCBB minus the classic dive "
          "(over the problems where one ran: '-' where the quick search proved all) and minus the best known jointly "
          "compatible hypothesis (min over problems)")
    print_table(["n", "problems", "median ms", "p95 ms", "proven optimal", "min over dive", "mean over dive",
                 "min over best known", "short", "best known from"], rows)
    plot_cases(args.png)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    run_recorded(main)
