"""The overview's ranking: methods ranked in blocks (a scenario at a seed) by their suite's primary
metric, over only the blocks every ranked method ran, the Friedman test and Nemenyi critical
difference (``significance``) deciding which differences are more than noise. ``RULE`` states the
rule as the page does."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ...scoring.aggregate import OK
from .columns import Column
from .significance import ALPHA, RankTest, block_ranks, friedman_nemenyi
from .suites import Suite

REFERENCE_METHODS = ("oracle",)
RULE = (
    "Each suite is ranked on its own, and the suites of one kind of method together (overall). A block is one "
    "scenario (a scene at a difficulty, with its back end) at one seed; in each block the methods are ranked by the "
    "suite's primary metric, its track's (F1, higher is better, in an open loop; ATE, lower is better, in a closed "
    "loop; each page says which), ties sharing the mean of their places. A run that diverged (its NEES stayed above the "
    "chi-square 0.999 bound for 5 frames), is not ok, or has no value ranks after every other run of its block, "
    "tied with the others like it: it never wins a block. The oracle (the true association) is a reference, not a "
    "method, and is not ranked. Methods are compared only on blocks they all ran: of the choices \u201cthe blocks "
    "run by at least c methods, and the methods that ran every one of them\u201d the one with the most "
    "method \u00d7 block results is compared, and a method that missed one of its blocks is listed apart with what "
    "it missed, not ranked on fewer. The mean ranks over the N blocks of the k methods are tested with the Friedman "
    f"test in Iman and Davenport's F form at \u03b1 = {ALPHA} (Dem\u0161ar, JMLR 7, 2006); if it rejects, two "
    "methods differ when their mean ranks are at least the Nemenyi critical difference "
    "CD = q\u03b1 \u221a(k(k+1)/(6N)) apart. A method's place is 1 + the number of methods that differ from it and "
    "rank better, so methods the test cannot tell apart share a place; when the test does not reject, every method "
    "is 1st. A leaderboard folder without per-seed values (no runs.csv, written before it was) is ranked with its "
    "scenarios as the blocks (means over seeds).")


@dataclass
class Ranking:
    """One ranking: ``table`` a row per ranked method (``method``, ``place``, ``mean_rank``,
    ``last``: blocks where it diverged, was not ok or had no value), best first; ``left_out`` and
    ``scenarios_out`` say what was not compared and why."""

    title: str
    slug: str
    test: RankTest
    table: pd.DataFrame
    scenarios: int
    per_seed: bool
    left_out: dict[str, str] = field(default_factory=dict)
    scenarios_out: dict[str, str] = field(default_factory=dict)


def suite_blocks(suite: Suite, metric: Column | None = None) -> pd.DataFrame:
    """One row per block x method (no oracle): ``block``, ``scenario``, ``key`` (``metric``, signed
    so lower is better; +inf where the run cannot win), ``diverged``, ``ok``."""
    runs = suite.runs if suite.runs is not None else suite.table
    runs = runs[~runs["method"].isin(REFERENCE_METHODS)]
    metric = metric or suite.primary
    value = (1.0 if metric.better == "low" else -1.0) * runs[metric.key].astype(float)
    diverged = runs["diverged"].fillna(0).gt(0) if "diverged" in runs else pd.Series(False, index=runs.index)
    ok = (runs["status"] == OK) & np.isfinite(value) & ~diverged
    seed = runs["seed"].astype(str) if "seed" in runs else ""
    return pd.DataFrame({"block": suite.slug + "|" + runs["scenario"] + "|" + seed, "suite": suite.title,
                         "scenario": runs["scenario"], "method": runs["method"], "key": value.where(ok, np.inf),
                         "diverged": diverged, "ok": ok})


def compared(blocks: pd.DataFrame) -> tuple[list[str], list[str]]:
    """The methods and blocks to compare: for each c, the blocks at least c methods ran and the
    methods that ran them all; the choice with the most results (then methods)."""
    ran = {m: set(b) for m, b in blocks.groupby("method")["block"]}
    count = blocks.groupby("block")["method"].nunique()
    best: tuple[int, int, list[str], list[str]] = (-1, -1, [], [])
    for c in sorted(set(count), reverse=True):
        kept = [b for b in dict.fromkeys(blocks["block"]) if count[b] >= c]
        methods = sorted(m for m, b in ran.items() if b.issuperset(kept))
        score = (len(methods) * len(kept), len(methods))
        if score > best[:2]:
            best = (*score, methods, kept)
    return best[2], best[3]


def rank(suites: list[Suite], title: str, slug: str) -> Ranking:
    """The ranking of the methods of ``suites`` over the blocks they all ran."""
    blocks = pd.concat([suite_blocks(s) for s in suites], ignore_index=True)
    methods, kept = compared(blocks)
    mine = blocks[blocks["block"].isin(kept) & blocks["method"].isin(methods)]
    keys = mine.pivot(index="block", columns="method", values="key").loc[kept, methods]
    test = friedman_nemenyi(block_ranks(keys.to_numpy(float)), tuple(methods))
    last = (~mine.set_index("method")["ok"]).groupby(level=0).sum()
    table = pd.DataFrame({"method": methods, "place": test.places() if methods else [], "mean_rank": test.mean_rank,
                          "last": [int(last.get(m, 0)) for m in methods]})
    table = table.sort_values(["mean_rank", "method"], kind="stable").reset_index(drop=True)
    per_seed = all(s.runs is not None for s in suites)
    scenarios = len(mine.drop_duplicates(["suite", "scenario"]))
    return Ranking(title, slug, test, table, scenarios, per_seed,
                   _left_out(blocks, methods, kept, suites), _scenarios_out(blocks, kept))


def _left_out(blocks: pd.DataFrame, methods: list[str], kept: list[str], suites: list[Suite]) -> dict[str, str]:
    """Each method not ranked, and what it did not run of the compared blocks."""
    out = {}
    wanted = blocks[blocks["block"].isin(kept)].drop_duplicates("block")
    for method in sorted(set(blocks["method"]) - set(methods)):
        missing = wanted[~wanted["block"].isin(blocks.loc[blocks["method"] == method, "block"])]
        absent, partly = [], []
        for s in suites:
            gone = missing[missing["suite"] == s.title]
            if len(gone) and len(gone) == (wanted["suite"] == s.title).sum() and len(suites) > 1:
                absent.append(s.title)
            elif len(gone):
                partly.append(f"did not run {_listed(list(dict.fromkeys(gone['scenario'])))}"
                              + (f" of {s.title}" if len(suites) > 1 else ""))
        present = [s.title for s in suites if s.title not in absent]
        where = (f"only in {' and '.join(present)}" if len(present) < len(absent) else f"not in {' and '.join(absent)}")
        out[method] = "; ".join(([where] if absent else []) + partly)
    return out


def _scenarios_out(blocks: pd.DataFrame, kept: list[str]) -> dict[str, str]:
    """Each scenario with a block not compared, and which methods ran it."""
    out = {}
    for (suite, scenario), rows in blocks[~blocks["block"].isin(kept)].groupby(["suite", "scenario"], sort=False):
        out[f"{scenario} ({suite})"] = f"run only by {_listed(sorted(set(rows['method'])))}"
    return out


def _listed(names: list[str], most: int = 4) -> str:
    """``a, b, c`` or ``a, b, c, d and 3 more``."""
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most else "")


def rankings(suites: list[Suite], group: str) -> list[Ranking]:
    """A ranking per suite, then (for two suites or more) the overall one, named ``group``."""
    out = [rank([s], s.title, s.slug) for s in suites]
    if len(suites) > 1:
        out.append(rank(suites, f"{group}, overall", f"overall-{group.split()[0].lower()}"))
    return out
