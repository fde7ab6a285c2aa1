"""``assocbench check``: compare a suite's accuracy with a committed baseline. It passes only when
it compared everything: every (scenario, method) row in the baseline and the fresh run, every
``status`` ``ok``, every guarded value finite on both sides and no worse than the baseline by more
than its tolerance. The guarded columns are the track's (``Track.guards``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import Role, atomic_path
from ..errors import UserError
from ..scoring.aggregate import OK
from ..tracks.base import GuardedMetric
from ..validation import check_number

KEY = ["scenario", "method"]
FINDING_COLUMNS = KEY + ["metric", "baseline", "current", "delta", "why"]


def check_tolerance(value, where: str = "--tolerance") -> float:
    """A tolerance is a finite, non-negative number (NaN would make every comparison pass)."""
    return float(check_number(value, where, lo=0))


def read_baseline(path: Path, guards: tuple[GuardedMetric, ...], suite: str = "ci",
                  default: bool = False) -> pd.DataFrame:
    """The baseline CSV (``scenario, method`` and every guarded column in range), or a one-line
    error for one that cannot vouch for anything (missing, empty, truncated, non-numeric, a guarded
    column lacking). ``default``: the default path, relative to the working folder."""
    if not path.is_file():
        how = "" if suite == "ci" else f" --suite {suite}"
        where = (f" in {Path.cwd()}: check guards a clone of assocbench (its baselines are the clone's results/); "
                 f"run it from the clone's root, pass --baseline PATH, or write one for your own suite with "
                 f"`assocbench check{how} --update`") if default else \
            f" (pass the path of an existing baseline, or write one with `assocbench check{how} --update`)"
        raise UserError(f"baseline {path} not found{where}")
    try:
        base = pd.read_csv(path, dtype={"scenario": str, "method": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise UserError(f"baseline {path} is not a readable CSV: {str(exc).strip().splitlines()[0]}") from None
    missing = [c for c in KEY + [g.name for g in guards if g.required] if c not in base.columns]
    if missing:
        raise UserError(f"baseline {path} lacks columns {', '.join(missing)} that suite {suite} guards; regenerate "
                        "it with --update")
    if base.empty:
        raise UserError(f"baseline {path} has no rows, so nothing could be compared; regenerate it with --update")
    for g in [g for g in guards if g.name in base.columns]:
        values = pd.to_numeric(base[g.name], errors="coerce")
        bad = ~values.between(g.lo, g.hi) | ~np.isfinite(values)   # NaN (empty, text, a truncated row) is not between
        if bad.any():
            row = int(bad.to_numpy().argmax())
            where = f"in [{g.lo:g}, {g.hi:g}]" if math.isfinite(g.hi) else f">= {g.lo:g}"
            raise UserError(f"baseline {path} row {row + 2}: {g.name} is {base[g.name].iloc[row]!r}, not a number "
                            f"{where} (truncated or edited?); regenerate it with --update")
        base[g.name] = values
    dup = base.duplicated(KEY)
    if dup.any():
        r = base[dup].iloc[0]
        raise UserError(f"baseline {path} lists {r['scenario']} × {r['method']} twice; regenerate it with --update")
    return base


def compare(current: pd.DataFrame, baseline: pd.DataFrame, guards: tuple[GuardedMetric, ...],
            tolerances: dict[str, float], expected: list[tuple[str, str]]) -> pd.DataFrame:
    """Findings that fail ``check``: a guarded column worse than the baseline by more than
    ``tolerances[guard.tolerance] · guard.scale``, a non-finite value, a status not ``ok``, an
    ``expected`` row missing on either side."""
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
        for g in [g for g in guards if g.name in base.columns]:
            b = float(base.loc[key, g.name])
            c = float(cur.loc[key, g.name]) if g.name in cur else math.nan
            slack = tolerances[g.tolerance] * g.scale
            if not math.isfinite(c):
                finding(key, "not a finite number", g.name, b, c)
            elif (c < b - slack) if g.higher_better else (c > b + slack):
                finding(key, "regressed", g.name, b, c)
    for key in base.index:
        if key not in set(expected):
            finding(key, "in the baseline but not in the suite")
    return pd.DataFrame(rows, columns=FINDING_COLUMNS)


def baseline_columns(guards: tuple[GuardedMetric, ...]) -> list[str]:
    """scenario, method and the guarded columns."""
    return KEY + [g.name for g in guards]


def write_ok_table(table: pd.DataFrame, columns: list[str], path: Path) -> None:
    """Write ``table[columns]`` as a baseline atomically; refused when a row is not ok (it cannot be
    the reference)."""
    bad = table[table["status"] != OK]
    if len(bad):
        r = bad.iloc[0]
        raise UserError(f"not writing baseline {path}: {r['scenario']} × {r['method']} is not ok ({r['status']})")
    with atomic_path(path, role=Role("baseline", "--baseline")) as tmp:
        table[columns].to_csv(tmp, index=False, float_format="%.6f")
