"""Leaderboard folders for the report's tests: copies of the committed ones, with a plugin's rows."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[3]
RESULTS = ROOT / "results"
PLUGIN = "mypkg.assoc:Mine"


def copy_leaderboard(src: Path, dst: Path) -> Path:
    """``dst`` holding ``src``'s leaderboard.csv and its pictures (not the Markdown)."""
    dst.mkdir(parents=True)
    for path in [src / "leaderboard.csv", *sorted(src.glob("leaderboard*.png"))]:
        shutil.copyfile(path, dst / path.name)
    return dst


def with_plugin(folder: Path, best: bool = True) -> Path:
    """Add a row per scenario for a user's method, ``best`` (or worst) by the suite's primary
    metric: F1 1.0 in an open loop, an ATE below every other in a closed one."""
    table = pd.read_csv(folder / "leaderboard.csv")
    rows = table.drop_duplicates("scenario").copy()
    rows["method"] = PLUGIN
    if "ate_rmse" in table:
        rows["ate_rmse"] = table["ate_rmse"].min() / 2 if best else table["ate_rmse"].max() * 2
    else:
        rows["f1"] = 1.0 if best else 0.0
    pd.concat([table, rows]).to_csv(folder / "leaderboard.csv", index=False)
    return folder


def tiny_leaderboard(folder: Path, rows: list[dict]) -> Path:
    """A leaderboard folder holding only ``rows`` as its CSV."""
    folder.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(folder / "leaderboard.csv", index=False)
    return folder


def runs_leaderboard(folder: Path, runs: pd.DataFrame) -> Path:
    """A leaderboard folder as ``assocbench leaderboard`` writes it for a feature track: ``runs``
    (a row per scenario x method x seed) as runs.csv, and their means over seeds as leaderboard.csv."""
    folder.mkdir(parents=True, exist_ok=True)
    runs.to_csv(folder / "runs.csv", index=False)
    grouped = runs.groupby(["scenario", "method"], sort=False)
    means = grouped.mean(numeric_only=True).drop(columns="seed")
    means["status"] = grouped["status"].agg(lambda s: "ok" if (s == "ok").all() else s[s != "ok"].iloc[0])
    means.assign(seeds=grouped.size()).reset_index().to_csv(folder / "leaderboard.csv", index=False)
    return folder
