"""Does the simulation predict the real ranking? Each method's mean rank over the scenarios of a
simulated leaderboard against its mean rank over a recorded one, by a metric (default: the suites'
primary one) and ranked as the report ranks them (harness.report.ranking: ok rows by the metric,
ties sharing places, a row that is not ok after every ok one; but a run that diverged keeps its value), over the methods the two share, and
Spearman's rank correlation of the two. With --by backend the scenarios of each back end (the
``-ekf`` / ``-isam2`` ending of a difficulty) are compared apart; otherwise a last table gives the
correlation per difficulty of each. With n methods, |ρ| must reach 0.9 (n = 5) or 0.7 (n = 8) to
be significant at 5 %.

    python benchmarks/sim_vs_real.py results results/real/photos
    python benchmarks/sim_vs_real.py results/planar results/real/victoria --by backend --metric ate_rmse f1

Arguments are leaderboard folders (or their leaderboard.csv) written by `assocbench leaderboard`.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from _util import print_markdown, run_recorded
from scipy.stats import spearmanr

from assocbench.errors import UserError
from assocbench.harness.report.columns import Column, column
from assocbench.harness.report.ranking import REFERENCE_METHODS, suite_blocks
from assocbench.harness.report.suites import Suite, read_suite

ALL = "all"


def shared_methods(sim: Suite, real: Suite, asked: list[str] | None) -> list[str]:
    """The methods both leaderboards rank (``asked``: these, each of which must be in both)."""
    both = sorted(set(sim.table["method"]) & set(real.table["method"]) - set(REFERENCE_METHODS))
    if asked:
        missing = [m for m in asked if m not in both]
        if missing:
            raise UserError(f"method {missing[0]} is not ranked on both leaderboards (both rank {', '.join(both)})")
        return list(asked)
    if len(both) < 3:
        raise UserError(f"the leaderboards share {len(both)} methods ({', '.join(both) or 'none'}): a rank "
                        "correlation needs 3 or more")
    return both


def mean_ranks(suite: Suite, methods: list[str], metric: Column, difficulty: str = ALL) -> pd.Series:
    """Each method's mean rank (1 best) by ``metric`` over the suite's scenarios (of one
    ``difficulty``), ranked among ``methods`` only."""
    table = suite.table[suite.table["method"].isin(methods)]
    if difficulty != ALL:
        table = table[table["difficulty"] == difficulty]
    # a scenario is a block (means over seeds); a diverged run keeps its value here, where the report
    # ranks it last: on Victoria Park every method but the reference diverges, and its ATE still tells them apart
    blocks = suite_blocks(replace(suite, table=table.assign(diverged=0), runs=None), metric)
    blocks["rank"] = blocks.groupby("block")["key"].rank(method="average")
    return blocks.groupby("method")["rank"].mean().reindex(methods)


def mean_metric(suite: Suite, methods: list[str], metric: Column) -> pd.Series:
    """Each method's ``metric``, averaged over the suite's scenarios; NaN where a scenario has none
    (every frame failed): an average of the others would flatter it."""
    return suite.table.groupby("method")[metric.key].agg(lambda v: v.mean(skipna=False)).reindex(methods)


def backends(suite: Suite) -> list[str]:
    """The back ends of ``suite``'s scenarios (``hard-ekf`` -> ``ekf``), in their order."""
    return list(dict.fromkeys(suite.table["backend"]))


def on_backend(suite: Suite, backend: str) -> Suite:
    """``suite`` cut to the scenarios of one back end (``ALL``: every scenario)."""
    if backend == ALL:
        return suite
    table = suite.table[suite.table["backend"] == backend]
    if table.empty:
        raise UserError(f"{suite.source} has no scenario on back end {backend!r} (it has {', '.join(backends(suite))})")
    return replace(suite, table=table, runs=None)


def rho(a: pd.Series, b: pd.Series) -> float:
    """Spearman's rank correlation of two series over the same methods (NaN where either is constant)."""
    if a.nunique() < 2 or b.nunique() < 2:
        return float("nan")
    return float(spearmanr(a.to_numpy(), b.to_numpy()).statistic)


def rank_table(sim: Suite, real: Suite, methods: list[str], metric: Column) -> tuple[pd.DataFrame, float]:
    """One row per method (best on the real data first) and Spearman's ρ of the mean ranks."""
    s, r = mean_ranks(sim, methods, metric), mean_ranks(real, methods, metric)
    table = pd.DataFrame({"method": methods, "sim_metric": mean_metric(sim, methods, metric).to_numpy(),
                          "sim_rank": s.to_numpy(), "real_metric": mean_metric(real, methods, metric).to_numpy(),
                          "real_rank": r.to_numpy()})
    table["shift"] = table["real_rank"] - table["sim_rank"]
    return table.sort_values(["real_rank", "method"]).reset_index(drop=True), rho(s, r)


def difficulty_table(sim: Suite, real: Suite, methods: list[str], metric: Column) -> pd.DataFrame:
    """Spearman's ρ of the mean ranks, per difficulty of the simulated suite (rows) and the real one."""
    def levels(suite: Suite) -> list[str]:
        return [ALL] + list(dict.fromkeys(suite.table["difficulty"]))

    rows = {d: {e: rho(mean_ranks(sim, methods, metric, d), mean_ranks(real, methods, metric, e)) for e in levels(real)}
            for d in levels(sim)}
    return pd.DataFrame(rows).T


def _num(value: float) -> str:
    return "n/a" if np.isnan(value) else f"{value:.3f}"


def markdown(table: pd.DataFrame, correlation: float, sim: Suite, real: Suite, metric: Column) -> str:
    """The rank table and its correlation, as Markdown."""
    head = [f"| method | sim {metric.label} | sim rank | real {metric.label} | real rank | shift |",
            "|---|---|---|---|---|---|"]
    rows = [f"| {r.method} | {_num(r.sim_metric)} | {r.sim_rank:.2f} | {_num(r.real_metric)} | {r.real_rank:.2f} | "
            f"{r.shift:+.2f} |" for r in table.itertuples()]
    n_sim, n_real = sim.table["scenario"].nunique(), real.table["scenario"].nunique()
    scenarios = (f"{n_sim} simulated scenario{'s' * (n_sim != 1)} ({', '.join(sorted(sim.table['scene'].unique()))} "
                 f"x {', '.join(dict.fromkeys(sim.table['difficulty']))}), {n_real} real one{'s' * (n_real != 1)} "
                 f"({', '.join(sorted(real.table['scene'].unique()))} x {', '.join(dict.fromkeys(real.table['difficulty']))})")
    return "\n".join(head + rows + ["", f"Spearman's rank correlation of the mean ranks: ρ = {correlation:+.2f} over "
                                          f"{len(table)} methods ({', '.join(sorted(table['method']))}); {scenarios}.", ""])


def difficulty_markdown(by_difficulty: pd.DataFrame) -> str:
    """The per-difficulty correlations, as Markdown."""
    cols = list(by_difficulty.columns)
    lines = ["| ρ: sim \\ real | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    lines += [f"| {d} | " + " | ".join("n/a" if np.isnan(v) else f"{v:+.2f}" for v in row) + " |"
              for d, row in by_difficulty.iterrows()]
    return "\n".join(lines) + "\n"


def report(sim: Suite, real: Suite, methods: list[str], metrics: list[Column], by_backend: bool) -> str:
    """Every table: per metric (and back end), the ranks and ρ; without back ends, ρ per difficulty."""
    parts = []
    for metric in metrics:
        for backend in backends(real) if by_backend else [ALL]:
            s, r = on_backend(sim, backend), on_backend(real, backend)
            parts.append(f"### {metric.label}" + ("" if backend == ALL else f", back end {backend}") + "\n")
            parts.append(markdown(*rank_table(s, r, methods, metric), s, r, metric))
            if not by_backend:
                parts.append(difficulty_markdown(difficulty_table(sim, real, methods, metric)))
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sim", type=Path, help="the simulated suite's leaderboard folder (or its CSV)")
    parser.add_argument("real", type=Path, help="the recorded suite's leaderboard folder (or its CSV)")
    parser.add_argument("--methods", nargs="+", help="the methods to compare (default: every method both rank)")
    parser.add_argument("--metric", nargs="+", help="the leaderboard columns to rank by (default: the primary one)")
    parser.add_argument("--by", choices=["backend"], help="compare the scenarios of each back end apart")
    args = parser.parse_args(argv)
    try:
        sim, real = read_suite(args.sim, str(args.sim)), read_suite(args.real, str(args.real))
        methods = shared_methods(sim, real, args.methods)
        metrics = [sim.primary] if not args.metric else [metric_of(sim, real, key) for key in args.metric]
        text = report(sim, real, methods, metrics, args.by == "backend")
    except UserError as exc:
        print(f"sim_vs_real: error: {exc}", file=sys.stderr)
        return 2
    print_markdown(text)
    return 0


def metric_of(sim: Suite, real: Suite, key: str) -> Column:
    """The catalogue's column ``key``, which both leaderboards must have."""
    for suite in (sim, real):
        if key not in suite.table:
            raise UserError(f"{suite.source} has no column {key!r}: give a metric both leaderboards have")
    found = column(key)
    if not found.better:
        raise UserError(f"{key!r} is not a metric with a direction (higher or lower better): rank by another column")
    return found


if __name__ == "__main__":
    run_recorded(main)
