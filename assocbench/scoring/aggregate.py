"""Aggregate per-frame records into a run summary and runs into a leaderboard.

precision = ΣTP / Σ(TP + FP), recall = ΣTP / Σ(TP + FN), F1 = 2PR / (P + R) (micro averages over
frames); perfect = share of frames with candidates whose association equals the truth (a failed
frame is not perfect); surprisal_gap = mean of s(returned) - s(true); runtime median and p95 of
``associate`` (ms); proven_optimal = share of frames whose answer the method proved optimal (NaN
where it does not say); true_mass = mean probability a soft associator puts on the true outcome
(``metrics.true_mass``).

A ratio with nothing to count is NaN, never 1 (an empty answer is trivially exact and compatible).
``status`` is ``ok`` or every reason the numbers cannot be trusted (failed frames, no candidates, no
true pair, nothing associated), so a broken run never reads as a perfect one; ``check`` fails every
row that is not ``ok``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from .loop_summary import LOOP_COLUMNS, loop_status, loop_summary

ACCURACY_METRICS = ("precision", "recall", "f1", "perfect")
SUMMARY_COLUMNS = ("status", "precision", "recall", "f1", "perfect", "surprisal_gap", "jc_share",
                   "clutter_accepted", "runtime_median_ms", "runtime_p95_ms", "frames", "failures", "timed_out",
                   "proven_optimal", "true_mass")
REPORTED_METRICS = ("proven_optimal", "true_mass")   # only some methods report these; NaN for the others
OK = "ok"


def _ratio(num: float, den: float) -> float:
    return float(num / den) if den > 0 else float("nan")


def run_status(frames: pd.DataFrame) -> str:
    """``ok``, or the reasons a run's numbers cannot be trusted, joined by ``; ``."""
    reasons = []
    failures = int((frames["error"] != "").sum()) if "error" in frames else 0
    if len(frames) == 0:
        reasons.append("no frames")
    if failures:
        reasons.append(f"{failures}/{len(frames)} frames failed")
    if len(frames) and frames["n"].sum() == 0:
        reasons.append("no candidates in any frame")
    else:
        if len(frames) and "n_true" in frames and frames["n_true"].sum() == 0:
            reasons.append("no true pair in any frame")   # recall has nothing to count, every pairing is false
        if len(frames) and (frames["tp"] + frames["fp"]).sum() == 0:
            reasons.append("nothing associated")
    if "nees" in frames:   # a closed-loop run
        reasons += loop_status(frames)
    return "; ".join(reasons) or OK


def _perfect_share(frames: pd.DataFrame) -> float:
    """Share of frames with candidates whose association is exactly right (a failed frame never is);
    NaN if no frame has candidates."""
    posed = frames[frames["n"] > 0]
    if not len(posed):
        return float("nan")
    right = posed["perfect"] & (posed["error"] == "") if "error" in posed else posed["perfect"]
    return float(right.mean())


def _reported_mean(ok: pd.DataFrame, column: str) -> float:
    """Mean of a column a method may leave NaN (it does not report it); NaN if no frame has it."""
    values = ok[column].dropna() if column in ok else pd.Series(dtype=float)
    return float(values.mean()) if len(values) else float("nan")


def summarize(frames: pd.DataFrame) -> dict[str, float]:
    """Summary metrics of one run's per-frame records; a closed-loop run's also gets
    ``loop_summary``'s columns."""
    ok = frames[frames["error"] == ""] if "error" in frames else frames
    tp, fp, fn = frames["tp"].sum(), frames["fp"].sum(), frames["fn"].sum()
    precision, recall = _ratio(tp, tp + fp), _ratio(tp, tp + fn)
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else precision + recall  # 0 or NaN
    runtime_ms = ok["runtime_s"].to_numpy() * 1e3
    gap = (ok["surprisal"] - ok["surprisal_true"]).to_numpy()
    paired_any = tp + fp > 0
    return {
        "status": run_status(frames), "precision": precision, "recall": recall, "f1": f1,
        "perfect": _perfect_share(frames) if paired_any or tp + fn > 0 else np.nan,
        "surprisal_gap": float(np.nanmean(gap)) if paired_any and np.isfinite(gap).any() else np.nan,
        "jc_share": float(ok["jointly_compatible"].mean()) if paired_any and len(ok) else np.nan,
        "clutter_accepted": int(frames["clutter_accepted"].sum()),
        "runtime_median_ms": float(np.median(runtime_ms)) if len(runtime_ms) else np.nan,
        "runtime_p95_ms": float(np.percentile(runtime_ms, 95)) if len(runtime_ms) else np.nan,
        "frames": int(len(frames)), "failures": int((frames["error"] != "").sum()) if "error" in frames else 0,
        "timed_out": int(frames["timed_out"].sum()) if "timed_out" in frames else 0,
        "proven_optimal": _reported_mean(ok, "proven_optimal"),
        "true_mass": _reported_mean(ok, "true_mass"),
    } | (loop_summary(frames) if "nees" in frames else {})


def leaderboard_table(summaries: pd.DataFrame, extra: Sequence[str] = ()) -> pd.DataFrame:
    """Mean and std over seeds of each method × scenario (shared metrics and the track's ``extra``),
    by scenario, not-ok rows last, then F1 (closed loop: ATE, with ``diverged`` seeds counted). A
    NaN seed makes the mean NaN; ``status`` is ``ok`` only when every seed's was."""
    metrics = ["precision", "recall", "f1", "perfect", "surprisal_gap", "runtime_median_ms", *REPORTED_METRICS]
    loop = "ate_rmse" in summaries
    if loop:   # a closed-loop suite: the trajectory, consistency and map columns too
        metrics += [c for c in LOOP_COLUMNS if c not in ("anees_lo", "anees_hi", "diverged_at")]
        summaries = summaries.assign(diverged=(summaries["diverged_at"] >= 0).astype(float))
    optional = list(REPORTED_METRICS) + (["revisits", "loop_closures", "ate_smoothed"] if loop else [])   # older results lack them
    metrics += [c for c in extra if c in summaries and c not in metrics]
    summaries = summaries.assign(**{c: np.nan for c in optional if c not in summaries})
    grouped = summaries.groupby(["scenario", "method"], sort=True)
    mean = grouped[metrics].agg(lambda col: col.mean(skipna=False))
    std = grouped[metrics].std(ddof=0).fillna(0.0)
    table = mean.join(std.add_suffix("_std"))
    table["status"] = grouped[["status", "failures", "frames"]].apply(_combined_status) if "status" in summaries else OK
    table["seeds"] = grouped.size()
    table["frames"] = grouped["frames"].sum()
    table["failures"] = grouped["failures"].sum()
    table["timed_out"] = grouped["timed_out"].sum()
    if loop:
        table["diverged"] = grouped["diverged"].sum().astype(int)
        table[["anees_lo", "anees_hi"]] = grouped[["anees_lo", "anees_hi"]].mean()
        table = table.reset_index().assign(_bad=lambda t: t["status"] != OK)
        table = table.sort_values(["scenario", "_bad", "ate_rmse", "method"]).drop(columns="_bad")
        return table.reset_index(drop=True)
    table = table.reset_index().assign(_bad=lambda t: t["status"] != OK)   # a run not ok never ranks first
    table = table.sort_values(["scenario", "_bad", "f1", "precision", "method"],
                              ascending=[True, True, False, False, True]).drop(columns="_bad")
    return table.reset_index(drop=True)


def _combined_status(runs: pd.DataFrame) -> str:
    """A leaderboard row's status from its seeds: failed frames summed, other reasons with their
    seed counts."""
    reasons = []
    failures, frames = int(runs["failures"].sum()), int(runs["frames"].sum())
    if failures:
        reasons.append(f"{failures}/{frames} frames failed")
    others = [r for status in runs["status"] for r in status.split("; ") if r != OK and "frames failed" not in r]
    for reason in dict.fromkeys(others):
        reasons.append(reason if len(runs) == 1 else f"{reason} in {others.count(reason)} of {len(runs)} seeds")
    return "; ".join(reasons) or OK
