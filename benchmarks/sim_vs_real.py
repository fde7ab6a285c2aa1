"""Does the simulation predict the real ranking? Each method's rank on a committed simulated
leaderboard against its rank on a real one, per back end, with Spearman's rank correlation.

A method's simulated rank is its mean rank over the simulated scenarios of that back end (each
scenario ranked by the metric, ties sharing their mean place, as the report ranks), then ranked;
its real rank is its place on the real scenario of that back end. Only methods on both
leaderboards count, the oracle (the reference association) never. Prints a Markdown table per back
end and metric, with the methods and scenarios used; ρ of n methods needs n ≥ 3, and with 5
methods only |ρ| ≥ 0.9 is significant at 5 %.
Usage: python benchmarks/sim_vs_real.py [--sim results/planar/leaderboard.csv] [--real results/real/victoria/leaderboard.csv] [--metric ate_rmse f1]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from scipy.stats import spearmanr

HIGHER_BETTER = {"f1": True, "precision": True, "recall": True, "pair_precision": True, "pair_recall": True}
EXCLUDED = ("oracle",)


def backend_of(scenario: str) -> str:
    """``park/hard-ekf`` -> ``ekf`` (the difficulty's suffix); ``""`` when it has none."""
    difficulty = scenario.rpartition("/")[2]
    return difficulty.rpartition("-")[2] if "-" in difficulty else ""


def ranks(table: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Rank (1 best, ties averaged) of each method within each scenario of ``table``."""
    out = table[["scenario", "method"]].copy()
    ascending = not HIGHER_BETTER.get(metric, False)
    out["rank"] = table.groupby("scenario")[metric].rank(ascending=ascending, method="average")
    return out


def compare(sim: pd.DataFrame, real: pd.DataFrame, metric: str, backend: str) -> tuple[pd.DataFrame, float, list[str]]:
    """Per method: mean simulated rank, simulated place, real value and real place; Spearman's ρ
    between the places; the simulated scenarios used."""
    methods = sorted((set(sim["method"]) & set(real["method"])) - set(EXCLUDED))
    sim = sim[sim["method"].isin(methods) & (sim["scenario"].map(backend_of) == backend)]
    real = real[real["method"].isin(methods) & (real["scenario"].map(backend_of) == backend)]
    mean_rank = ranks(sim, metric).groupby("method")["rank"].mean()
    real_value = real.groupby("method")[metric].mean()
    out = pd.DataFrame({"sim mean rank": mean_rank, "sim place": mean_rank.rank(method="average"),
                        f"real {metric}": real_value,
                        "real place": real_value.rank(ascending=not HIGHER_BETTER.get(metric, False), method="average")})
    rho = float(spearmanr(out["sim place"], out["real place"]).statistic) if len(out) >= 3 else float("nan")
    return out.sort_values("real place"), rho, sorted(sim["scenario"].unique())


def places(sim: pd.DataFrame, real: pd.DataFrame, metrics: list[str], backends: list[str]) -> list[str]:
    """One Markdown table of every method's simulated and real place for each metric and back end
    (``back end`` columns joined by " / "), and a last row of Spearman's ρ (the docs page's table)."""
    results = {(m, b): compare(sim, real, m, b) for m in metrics for b in backends}
    methods = sorted(set.union(*(set(t.index) for t, _, _ in results.values())),
                     key=lambda name: [results[metrics[0], b][0].loc[name, "sim place"] for b in backends])
    head = [f"{where} place {m} ({' / '.join(backends)})" for m in metrics for where in ("sim", "real")]
    lines = ["| method | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for name in methods:
        cells = [" / ".join(f"{results[m, b][0].loc[name, f'{where} place']:g}" for b in backends)
                 for m in metrics for where in ("sim", "real")]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    rhos = [" / ".join(f"{results[m, b][1]:.2f}" for b in backends) for m in metrics]
    lines.append("| **Spearman ρ** | " + " | ".join(cell for rho in rhos for cell in ("", f"**{rho}**")) + " |")
    return lines + [""]


def markdown(sim_path: Path, real_path: Path, metrics: list[str]) -> str:
    """The sim-vs-real tables (module docstring) as Markdown: all places in one table, then one
    table per back end and metric with the values and the scenarios used."""
    sim, real = pd.read_csv(sim_path), pd.read_csv(real_path)
    lines = places(sim, real, metrics, sorted(set(real["scenario"].map(backend_of))))
    for backend in sorted(set(real["scenario"].map(backend_of))):
        for metric in metrics:
            table, rho, scenarios = compare(sim, real, metric, backend)
            lines += [f"**{backend or 'all'}, {metric}** (Spearman ρ = {rho:.2f} over {len(table)} methods; simulated: "
                      f"{', '.join(scenarios)}; real: {', '.join(sorted(real['scenario'][real['scenario'].map(backend_of) == backend].unique()))})",
                      "", "| method | sim mean rank | sim place | real " + metric + " | real place |", "|---|---|---|---|---|"]
            lines += [f"| {m} | {r['sim mean rank']:.2f} | {r['sim place']:g} | {r[f'real {metric}']:.4g} | "
                      f"{r['real place']:g} |" for m, r in table.iterrows()]
            lines.append("")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sim", type=Path, default=Path("results/planar/leaderboard.csv"))
    p.add_argument("--real", type=Path, default=Path("results/real/victoria/leaderboard.csv"))
    p.add_argument("--metric", nargs="+", default=["ate_rmse", "f1"])
    args = p.parse_args()
    print(markdown(args.sim, args.real, args.metric))


if __name__ == "__main__":
    main()
