"""``assocbench check``: compare a suite's accuracy with a committed baseline."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..atomic import atomic_path
from ..errors import UserError
from ..scoring.aggregate import ACCURACY_METRICS, leaderboard_table

KEY = ["scenario", "method"]


def read_baseline(path: Path) -> pd.DataFrame:
    """The baseline CSV (``scenario, method`` and the accuracy metrics), or a one-line error."""
    if not path.is_file():
        raise UserError(f"baseline {path} not found: create it with `assocbench check --update`")
    try:
        base = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise UserError(f"baseline {path} is not a readable CSV: {exc}") from None
    missing = [c for c in KEY + list(ACCURACY_METRICS) if c not in base.columns]
    if missing:
        raise UserError(f"baseline {path} lacks columns {', '.join(missing)}; regenerate it with --update")
    return base


def compare(current: pd.DataFrame, baseline: pd.DataFrame, tolerance: float) -> pd.DataFrame:
    """Rows (scenario, method, metric, baseline, current, delta) that regressed by more than
    ``tolerance`` or are missing from the current results."""
    merged = baseline[KEY + list(ACCURACY_METRICS)].merge(
        current[KEY + list(ACCURACY_METRICS)], on=KEY, how="left", suffixes=("_base", ""))
    rows = []
    for _, r in merged.iterrows():
        for metric in ACCURACY_METRICS:
            base, now = r[f"{metric}_base"], r[metric]
            if pd.isna(now) or now < base - tolerance:
                rows.append({"scenario": r["scenario"], "method": r["method"], "metric": metric,
                             "baseline": base, "current": now, "delta": now - base})
    return pd.DataFrame(rows, columns=KEY + ["metric", "baseline", "current", "delta"])


def baseline_table(summaries: pd.DataFrame) -> pd.DataFrame:
    """The rows written to the baseline: mean accuracy per scenario × method."""
    return leaderboard_table(summaries)[KEY + list(ACCURACY_METRICS)]


def write_baseline(summaries: pd.DataFrame, path: Path) -> None:
    with atomic_path(path) as tmp:
        baseline_table(summaries).to_csv(tmp, index=False, float_format="%.6f")
