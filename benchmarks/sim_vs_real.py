"""Does the simulation predict the real ranking? Each method's mean rank over the scenarios of a
simulated leaderboard against its mean rank over a recorded one, both by their suites' primary metric
and ranked as the report ranks them (harness.report.ranking: ok rows by the metric, ties sharing
places, a row that is not ok after every ok one), over the methods the two share, and Spearman's
rank correlation of the two. A second table gives the correlation per difficulty of each.

    python benchmarks/sim_vs_real.py results results/real/photos
    python benchmarks/sim_vs_real.py results/planar results/real/victoria_park --methods enn mnn jcbb

Arguments are leaderboard folders (or their leaderboard.csv) written by `assocbench leaderboard`.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import spearmanr

from assocbench.errors import UserError
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


def mean_ranks(suite: Suite, methods: list[str], difficulty: str = ALL) -> pd.Series:
    """Each method's mean rank (1 best) over the suite's scenarios (of one ``difficulty``), ranked
    among ``methods`` only."""
    table = suite.table[suite.table["method"].isin(methods)]
    if difficulty != ALL:
        table = table[table["difficulty"] == difficulty]
    blocks = suite_blocks(replace(suite, table=table, runs=None))  # a scenario is a block (means over seeds)
    blocks["rank"] = blocks.groupby("block")["key"].rank(method="average")
    return blocks.groupby("method")["rank"].mean().reindex(methods)


def mean_metric(suite: Suite, methods: list[str]) -> pd.Series:
    """Each method's primary metric, averaged over the suite's scenarios; NaN where a scenario has
    none (every frame failed): an average of the others would flatter it."""
    column = suite.table.groupby("method")[suite.primary.key]
    return column.agg(lambda v: v.mean(skipna=False)).reindex(methods)


def rho(a: pd.Series, b: pd.Series) -> float:
    """Spearman's rank correlation of two series over the same methods (NaN where either is constant)."""
    if a.nunique() < 2 or b.nunique() < 2:
        return float("nan")
    return float(spearmanr(a.to_numpy(), b.to_numpy()).statistic)


def rank_table(sim: Suite, real: Suite, methods: list[str]) -> tuple[pd.DataFrame, float]:
    """One row per method (best on the real data first) and Spearman's ρ of the mean ranks."""
    s, r = mean_ranks(sim, methods), mean_ranks(real, methods)
    table = pd.DataFrame({"method": methods, "sim_metric": mean_metric(sim, methods).to_numpy(), "sim_rank": s.to_numpy(),
                          "real_metric": mean_metric(real, methods).to_numpy(), "real_rank": r.to_numpy()})
    table["shift"] = table["real_rank"] - table["sim_rank"]
    return table.sort_values(["real_rank", "method"]).reset_index(drop=True), rho(s, r)


def difficulty_table(sim: Suite, real: Suite, methods: list[str]) -> pd.DataFrame:
    """Spearman's ρ of the mean ranks, per difficulty of the simulated suite (rows) and the real one."""
    def levels(suite: Suite) -> list[str]:
        return [ALL] + list(dict.fromkeys(suite.table["difficulty"]))

    rows = {d: {e: rho(mean_ranks(sim, methods, d), mean_ranks(real, methods, e)) for e in levels(real)}
            for d in levels(sim)}
    return pd.DataFrame(rows).T


def _num(value: float) -> str:
    return "n/a" if np.isnan(value) else f"{value:.3f}"


def markdown(table: pd.DataFrame, correlation: float, by_difficulty: pd.DataFrame, sim: Suite, real: Suite) -> str:
    """The two tables and the correlation, as Markdown."""
    metric = f"{sim.primary.label}" + ("" if sim.primary.key == real.primary.key else f" / {real.primary.label}")
    head = [f"| method | sim {metric} | sim rank | real {real.primary.label} | real rank | shift |", "|---|---|---|---|---|---|"]
    rows = [f"| {r.method} | {_num(r.sim_metric)} | {r.sim_rank:.2f} | {_num(r.real_metric)} | {r.real_rank:.2f} | "
            f"{r.shift:+.2f} |" for r in table.itertuples()]
    scenarios = (f"{sim.table['scenario'].nunique()} simulated scenarios ({', '.join(sorted(sim.table['scene'].unique()))} "
                 f"x {', '.join(dict.fromkeys(sim.table['difficulty']))}), {real.table['scenario'].nunique()} real ones "
                 f"({', '.join(sorted(real.table['scene'].unique()))} x {', '.join(dict.fromkeys(real.table['difficulty']))})")
    lines = head + rows + ["", f"Spearman's rank correlation of the mean ranks: ρ = {correlation:+.2f} over {len(table)} "
                                f"methods ({', '.join(sorted(table['method']))}); {scenarios}.", ""]
    cols = list(by_difficulty.columns)
    lines += ["| ρ: sim \\ real | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    lines += [f"| {d} | " + " | ".join("n/a" if np.isnan(v) else f"{v:+.2f}" for v in row) + " |"
              for d, row in by_difficulty.iterrows()]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sim", type=Path, help="the simulated suite's leaderboard folder (or its CSV)")
    parser.add_argument("real", type=Path, help="the recorded suite's leaderboard folder (or its CSV)")
    parser.add_argument("--methods", nargs="+", help="the methods to compare (default: every method both rank)")
    args = parser.parse_args(argv)
    try:
        sim, real = read_suite(args.sim, str(args.sim)), read_suite(args.real, str(args.real))
        methods = shared_methods(sim, real, args.methods)
    except UserError as exc:
        print(f"sim_vs_real: error: {exc}", file=sys.stderr)
        return 2
    table, correlation = rank_table(sim, real, methods)
    print(markdown(table, correlation, difficulty_table(sim, real, methods), sim, real), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
