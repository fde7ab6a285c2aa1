"""Each method's time per call and the largest problem it was given, over every stored run of a
leaderboard: the calls, the median, 95th percentile and longest wall time of one associate() call
(a failed call's time is what it ran before it failed or was stopped), the largest number of
candidates n and of measurements m of a frame it was called on, and its failed and timed-out frames.

    assocbench leaderboard --suite real_photos --out results/real/photos
    python benchmarks/call_sizes.py results/real/photos

The argument is the folder `assocbench leaderboard --out` wrote: its runs/ (the stored runs, which
the repository does not keep) are read through their manifests.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd
from _util import print_markdown, run_recorded

from assocbench.errors import UserError
from assocbench.harness.runstore import FOLDER


def stored_runs(folder: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every stored run's frames and summaries under ``folder/runs``, the files its manifests name."""
    store = folder / FOLDER
    manifests = sorted(store.glob("*.manifest.json"))
    if not manifests:
        raise UserError(f"{store} holds no stored run: give the folder `assocbench leaderboard --out` wrote")
    frames, summaries = [], []
    for path in manifests:
        info = json.loads(path.read_text())
        files = info["files"]
        method = info["run"].split(" on ", 1)[0]   # the store names a run "<method> on <scenario> seed <seed>"
        frames.append(pd.read_csv(store / files["frames"]["name"]).assign(method=method))
        summaries.append(pd.read_csv(store / files["summary"]["name"]).assign(method=method))
    return pd.concat(frames, ignore_index=True), pd.concat(summaries, ignore_index=True)


def call_table(frames: pd.DataFrame, summaries: pd.DataFrame) -> pd.DataFrame:
    """One row per method, in the order the runs list them."""
    ms = frames.assign(ms=frames["runtime_s"] * 1e3).groupby("method", sort=False)
    table = pd.DataFrame({"calls": ms.size(), "median_ms": ms["ms"].median(), "p95_ms": ms["ms"].quantile(0.95),
                          "max_ms": ms["ms"].max(), "largest_n": ms["n"].max(), "largest_m": ms["m"].max()})
    counts = summaries.groupby("method", sort=False)[["failures", "timed_out"]].sum()
    return table.join(counts).reset_index()


def markdown(table: pd.DataFrame) -> str:
    head = ["| method | calls | median ms | p95 ms | max ms | largest n | largest m | failed | timed out |",
            "|---|---|---|---|---|---|---|---|---|"]
    rows = [f"| {r.method} | {r.calls} | {r.median_ms:.3f} | {r.p95_ms:.3f} | {r.max_ms:.3f} | {r.largest_n} | "
            f"{r.largest_m} | {r.failures} | {r.timed_out} |" for r in table.itertuples()]
    return "\n".join(head + rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", type=Path, help="a leaderboard folder (assocbench leaderboard --out)")
    args = parser.parse_args(argv)
    try:
        runs = stored_runs(args.folder)
    except UserError as exc:
        print(f"call_sizes: error: {exc}", file=sys.stderr)
        return 2
    print_markdown(markdown(call_table(*runs)))
    return 0


if __name__ == "__main__":
    run_recorded(main)
