"""The overview's ranking: each method's rank in each scenario by its suite's primary metric, and
its mean over scenarios and suites.

In one scenario the methods whose row is ok are ranked by the primary metric (F1 higher is
better; ATE lower is better), ties sharing the mean of their places (1, 2.5, 2.5, 4); a row that
is not ok, or has no value, ranks after every ok one. The oracle (the true association) is a
reference, not a method, and is not ranked. A method's normalised rank in a scenario with n
ranked methods is (rank − 1) / (n − 1): 0 best, 1 last, so that scenarios with few and many
methods weigh alike; the overall score is its mean over every scenario of every suite."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...scoring.aggregate import OK
from .suites import Suite

REFERENCE_METHODS = ("oracle",)


def scenario_ranks(suite: Suite) -> pd.DataFrame:
    """One row per scenario x ranked method: ``rank`` (1 best), ``n`` (methods ranked), ``norm``
    ((rank − 1) / (n − 1), NaN when n is 1), ``ok``."""
    table = suite.table[~suite.table["method"].isin(REFERENCE_METHODS)]
    metric = suite.primary
    sign = 1.0 if metric.better == "low" else -1.0
    value = sign * table[metric.key].astype(float)
    usable = (table["status"] == OK) & value.notna()
    key = value.where(usable, np.inf)   # not ok or no value: after every ok row, tied among themselves
    ranks = key.groupby(table["scenario"]).rank(method="average")
    n = table.groupby("scenario")["method"].transform("size")
    norm = ((ranks - 1) / (n - 1)).where(n > 1)
    return pd.DataFrame({"scenario": table["scenario"], "method": table["method"], "rank": ranks, "n": n,
                         "norm": norm, "ok": usable})


def overview(suites: list[Suite]) -> pd.DataFrame:
    """One row per method: for each suite (by slug) its mean rank, and ``overall`` (mean normalised
    rank over all its scenarios), ``scenarios`` and ``not_ok`` counts; best overall first, then by name."""
    ranks = {s.slug: scenario_ranks(s) for s in suites}
    methods = sorted({m for r in ranks.values() for m in r["method"]})
    rows = []
    for method in methods:
        mine = {slug: r[r["method"] == method] for slug, r in ranks.items()}
        row = {"method": method} | {slug: float(r["rank"].mean()) if len(r) else np.nan for slug, r in mine.items()}
        every = pd.concat(list(mine.values()))
        row |= {"overall": float(every["norm"].mean()), "scenarios": len(every), "not_ok": int((~every["ok"]).sum())}
        rows.append(row)
    table = pd.DataFrame(rows)
    return table.sort_values(["overall", "method"], na_position="last", kind="stable").reset_index(drop=True)
