"""``assocbench check``: compare a suite's accuracy with a committed baseline.

``check`` passes only when it compared everything it was asked to: every (scenario, method)
row of the suite is in the baseline and in the fresh run, every run's ``status`` is ``ok`` (no
failed frames, candidates present, something associated), and every accuracy value on both
sides is finite and no more than ``tolerance`` (finite, >= 0) below the baseline.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import Role, atomic_path
from ..errors import UserError
from ..scoring.aggregate import ACCURACY_METRICS, OK, leaderboard_table
from ..validation import check_number

KEY = ["scenario", "method"]
FINDING_COLUMNS = KEY + ["metric", "baseline", "current", "delta", "why"]


def check_tolerance(value, where: str = "--tolerance") -> float:
    """A tolerance is a finite, non-negative number (NaN would make every comparison pass)."""
    return float(check_number(value, where, lo=0))


def read_baseline(path: Path, suite: str = "ci") -> pd.DataFrame:
    """The baseline CSV (``scenario, method`` and the accuracy metrics in [0, 1]), or a one-line
    error: a missing, empty, truncated or non-numeric baseline cannot vouch for anything."""
    if not path.is_file():
        how = "" if suite == "ci" else f" --suite {suite}"
        raise UserError(f"baseline {path} not found (run check from the repository root, or create it with "
                        f"`assocbench check{how} --update`)")
    try:
        base = pd.read_csv(path, dtype={"scenario": str, "method": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise UserError(f"baseline {path} is not a readable CSV: {str(exc).strip().splitlines()[0]}") from None
    missing = [c for c in KEY + list(ACCURACY_METRICS) if c not in base.columns]
    if missing:
        raise UserError(f"baseline {path} lacks columns {', '.join(missing)}; regenerate it with --update")
    if base.empty:
        raise UserError(f"baseline {path} has no rows, so nothing could be compared; regenerate it with --update")
    for metric in ACCURACY_METRICS:
        values = pd.to_numeric(base[metric], errors="coerce")
        bad = ~values.between(0.0, 1.0)   # NaN (empty, text, a truncated row) is not between
        if bad.any():
            row = int(bad.to_numpy().argmax())
            raise UserError(f"baseline {path} row {row + 2}: {metric} is {base[metric].iloc[row]!r}, not a number "
                            f"in [0, 1] (truncated or edited?); regenerate it with --update")
        base[metric] = values
    if "ate_rmse" in base:   # a closed loop's baseline: metres, finite and >= 0
        values = pd.to_numeric(base["ate_rmse"], errors="coerce")
        bad = ~(values >= 0) | ~np.isfinite(values)
        if bad.any():
            row = int(bad.to_numpy().argmax())
            raise UserError(f"baseline {path} row {row + 2}: ate_rmse is {base['ate_rmse'].iloc[row]!r}, not a "
                            f"number >= 0 (truncated or edited?); regenerate it with --update")
        base["ate_rmse"] = values
    dup = base.duplicated(KEY)
    if dup.any():
        r = base[dup].iloc[0]
        raise UserError(f"baseline {path} lists {r['scenario']} × {r['method']} twice; regenerate it with --update")
    return base


def compare(current: pd.DataFrame, baseline: pd.DataFrame, tolerance: float,
            expected: list[tuple[str, str]], ate_tolerance: float = 0.01) -> pd.DataFrame:
    """Findings (one row each) that make ``check`` fail: an accuracy metric more than
    ``tolerance`` below the baseline, a closed loop's ATE more than ``ate_tolerance`` (m) above
    it, a non-finite value, a run whose status is not ``ok``, or an ``expected`` row missing from
    the baseline or from the current results."""
    cur = current.set_index(KEY)
    base = baseline.set_index(KEY)
    rows = []

    def finding(key, why, metric="", b=math.nan, c=math.nan):
        rows.append({"scenario": key[0], "method": key[1], "metric": metric, "baseline": b, "current": c,
                     "delta": c - b, "why": why})

    for key in expected:
        if key not in base.index:
            finding(key, "not in the baseline (run check --update)")
            continue
        if key not in cur.index:
            finding(key, "not produced by this run")
            continue
        status = cur.loc[key, "status"] if "status" in cur else OK
        if status != OK:
            finding(key, f"run not ok: {status}")
        for metric in ACCURACY_METRICS:
            b, c = float(base.loc[key, metric]), float(cur.loc[key, metric])
            if not math.isfinite(c):
                finding(key, "not a finite number", metric, b, c)
            elif c < b - tolerance:
                finding(key, "regressed", metric, b, c)
        if "ate_rmse" in base.columns:   # a closed loop: lower is better
            b, c = float(base.loc[key, "ate_rmse"]), float(cur.loc[key, "ate_rmse"]) if "ate_rmse" in cur else math.nan
            if not math.isfinite(c):
                finding(key, "not a finite number", "ate_rmse", b, c)
            elif c > b + ate_tolerance:
                finding(key, "regressed", "ate_rmse", b, c)
    for key in base.index:
        if key not in set(expected):
            finding(key, "in the baseline but not in the suite")
    return pd.DataFrame(rows, columns=FINDING_COLUMNS)


def baseline_table(summaries: pd.DataFrame) -> pd.DataFrame:
    """The rows written to the baseline: mean accuracy per scenario × method (and a closed
    loop's ATE)."""
    table = leaderboard_table(summaries)
    return table[baseline_columns(table)]


def baseline_columns(table: pd.DataFrame) -> list[str]:
    """scenario, method, the accuracy metrics, and a closed loop's ATE when the table has it."""
    return KEY + list(ACCURACY_METRICS) + (["ate_rmse"] if "ate_rmse" in table else [])


def write_ok_table(table: pd.DataFrame, columns: list[str], path: Path) -> None:
    """Write ``table[columns]`` as a baseline atomically; refuse it when any row's status is not
    ok (a run that cannot vouch for anything must not become the reference)."""
    bad = table[table["status"] != OK]
    if len(bad):
        r = bad.iloc[0]
        raise UserError(f"not writing baseline {path}: {r['scenario']} × {r['method']} is not ok ({r['status']})")
    with atomic_path(path, role=Role("baseline", "--baseline")) as tmp:
        table[columns].to_csv(tmp, index=False, float_format="%.6f")


def write_baseline(summaries: pd.DataFrame, path: Path) -> None:
    """Write the baseline (``baseline_table``) atomically; refuse one from a run not ok."""
    table = leaderboard_table(summaries)
    write_ok_table(table, baseline_columns(table), path)
