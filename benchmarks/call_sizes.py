"""Time per call of each method and the largest problem it met, from a leaderboard folder's stored
frames (``<folder>/jobs/*.frames.csv``, written by ``assocbench leaderboard --out <folder>``).

Per scenario and method: frames, the median and 95th percentile of one ``associate()`` call (ms,
over every seed's frames), and the largest n (candidates) and m (measurements) of a frame. The
times are the machine's at the time of the leaderboard: compare them within one table only.
Usage: python benchmarks/call_sizes.py results/real/victoria_open [results/real/victoria]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd


def call_sizes(folder: Path) -> pd.DataFrame:
    """One row per scenario x method (module docstring)."""
    files = sorted((folder / "jobs").glob("*.frames.csv"))
    if not files:
        raise SystemExit(f"{folder} holds no jobs/*.frames.csv: give a folder written by `assocbench leaderboard --out`")
    frames = pd.concat([pd.read_csv(f) for f in files], ignore_index=True)
    grouped = frames.groupby(["scenario", "method"])
    return pd.DataFrame({"frames": grouped.size(),
                         "median ms": grouped["runtime_s"].median() * 1e3,
                         "p95 ms": grouped["runtime_s"].agg(lambda s: np.percentile(s, 95)) * 1e3,
                         "largest n": grouped["n"].max(), "largest m": grouped["m"].max()}).reset_index()


def markdown(table: pd.DataFrame) -> str:
    lines = ["| scenario | method | frames | median ms | p95 ms | largest n | largest m |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r.scenario} | {r.method} | {r.frames} | {r['median ms']:.3f} | {r['p95 ms']:.3f} | {r['largest n']} | "
              f"{r['largest m']} |" for _, r in table.iterrows()]
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folders", type=Path, nargs="+", help="leaderboard folders")
    for folder in p.parse_args().folders:
        print(f"{folder}\n\n{markdown(call_sizes(folder))}\n")


if __name__ == "__main__":
    main()
