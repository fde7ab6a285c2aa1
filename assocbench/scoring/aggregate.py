"""Aggregate per-frame records into a run summary and runs into a leaderboard.

precision = ΣTP / Σ(TP + FP),  recall = ΣTP / Σ(TP + FN),  F1 = 2PR / (P + R)  (micro averages
over frames); perfect = share of frames whose association equals the truth exactly;
surprisal_gap = mean over frames of s(returned) - s(true); runtime median and p95 of
``associate`` in milliseconds.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

ACCURACY_METRICS = ("precision", "recall", "f1", "perfect")
SUMMARY_COLUMNS = ("precision", "recall", "f1", "perfect", "surprisal_gap", "jc_share",
                   "clutter_accepted", "runtime_median_ms", "runtime_p95_ms", "frames", "failures", "timed_out")


def _ratio(num: float, den: float) -> float:
    return float(num / den) if den > 0 else 1.0


def summarize(frames: pd.DataFrame) -> dict[str, float]:
    """Summary metrics of one run's per-frame records (one row per frame)."""
    ok = frames[frames["error"] == ""] if "error" in frames else frames
    tp, fp, fn = frames["tp"].sum(), frames["fp"].sum(), frames["fn"].sum()
    precision, recall = _ratio(tp, tp + fp), _ratio(tp, tp + fn)
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    runtime_ms = ok["runtime_s"].to_numpy() * 1e3
    gap = (ok["surprisal"] - ok["surprisal_true"]).to_numpy()
    return {
        "precision": precision, "recall": recall, "f1": f1,
        "perfect": float(frames["perfect"].mean()) if len(frames) else 1.0,
        "surprisal_gap": float(np.nanmean(gap)) if np.isfinite(gap).any() else np.nan,
        "jc_share": float(ok["jointly_compatible"].mean()) if len(ok) else np.nan,
        "clutter_accepted": int(frames["clutter_accepted"].sum()),
        "runtime_median_ms": float(np.median(runtime_ms)) if len(runtime_ms) else np.nan,
        "runtime_p95_ms": float(np.percentile(runtime_ms, 95)) if len(runtime_ms) else np.nan,
        "frames": int(len(frames)), "failures": int((frames["error"] != "").sum()) if "error" in frames else 0,
        "timed_out": int(frames["timed_out"].sum()) if "timed_out" in frames else 0,
    }


def leaderboard_table(summaries: pd.DataFrame) -> pd.DataFrame:
    """Mean and std over seeds of each method × scenario, sorted by scenario then F1 (best first)."""
    metrics = ["precision", "recall", "f1", "perfect", "surprisal_gap", "runtime_median_ms"]
    grouped = summaries.groupby(["scenario", "method"], sort=True)
    mean = grouped[metrics].mean()
    std = grouped[metrics].std(ddof=0).fillna(0.0)
    table = mean.join(std.add_suffix("_std"))
    table["seeds"] = grouped.size()
    table["frames"] = grouped["frames"].sum()
    table["failures"] = grouped["failures"].sum()
    table["timed_out"] = grouped["timed_out"].sum()
    table = table.reset_index().sort_values(["scenario", "f1", "precision", "method"],
                                            ascending=[True, False, False, True])
    return table.reset_index(drop=True)
