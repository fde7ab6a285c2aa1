"""Summary of a closed-loop run (``harness.loop``). ate_rmse (m) and rot_rmse_deg: RMSE of position
and rotation errors with no alignment (as ``evo_ape tum truth.txt estimate.txt``), each pose as
estimated then; ate_smoothed: a smoother's final trajectory's ATE (a filter's equals ate_rmse);
anees: mean pose NEES where a covariance exists, with the 95 % band ``χ²_{qN}(0.025, 0.975) / N`` (q
= ``nees_dof``: 6 in space, 3 in the plane; it assumes independent frames, so one run scatters
wider); diverged_at: the first frame whose NEES stays above χ²_q(0.999) for 5 frames, -1 never. Map
columns are the last frame's (confirmed, duplicates, false landmarks, map_rmse); ``revisits`` and
``loop_closures`` are summed (``RevisitCounter``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .trajectory import anees, anees_band, divergence_frame

ESTIMATOR_FAILED = "EstimatorFailed"   # the error of the frames of a run whose estimator raised (harness.loop)
LOOP_COLUMNS = ("ate_rmse", "ate_smoothed", "rot_rmse_deg", "anees", "anees_lo", "anees_hi", "diverged_at", "map_size",
                "duplicates", "false_landmarks", "map_rmse", "new_landmarks", "no_depth", "revisits", "loop_closures")


def loop_summary(frames: pd.DataFrame) -> dict:
    """The closed-loop columns of a run's summary (see module docstring)."""
    if not len(frames):
        return {c: float("nan") for c in LOOP_COLUMNS}
    nees = frames["nees"].to_numpy(dtype=float)
    excluded = [0] if not np.isfinite(nees[0]) else []   # slam's first pose has no covariance
    counted = len(nees) - len(excluded)
    dof = int(frames["nees_dof"].iloc[0]) if "nees_dof" in frames else 6
    lo, hi = anees_band(counted, dof) if counted else (float("nan"), float("nan"))
    last = _last_estimated(frames)
    ate = float(np.sqrt(np.mean(frames["pos_err"].to_numpy(dtype=float) ** 2)))
    return {
        "ate_rmse": ate,
        "ate_smoothed": _smoothed(frames, ate),
        "rot_rmse_deg": float(np.sqrt(np.mean(frames["rot_err_deg"].to_numpy(dtype=float) ** 2))),
        "anees": anees(nees, exclude=excluded) if counted else float("nan"), "anees_lo": lo, "anees_hi": hi,
        "diverged_at": int(divergence_frame(np.nan_to_num(nees, nan=0.0), dof)),
        "map_size": _count(last["map_size"]), "duplicates": _count(last["duplicates"]),
        "false_landmarks": _count(last["false_landmarks"]), "map_rmse": float(last["map_rmse"]),
        "new_landmarks": int(frames.get("new_landmarks", pd.Series(0)).fillna(0).sum()),
        "no_depth": int(frames.get("no_depth", pd.Series(0)).fillna(0).sum()),
        "revisits": int(frames.get("revisits", pd.Series(0)).fillna(0).sum()),
        "loop_closures": int(frames.get("loop_closures", pd.Series(0)).fillna(0).sum()),
    }


BAND_MARKS = {"above": "▲", "below": "▼"}
BAND_LEGEND = ("▲ / ▼ beside an ANEES: it lies above / below its 95 % band, the filter overconfident (its "
               "covariance smaller than its errors) / pessimistic (larger)")


CHAOTIC_MARK = "†"
CHAOTIC_LEGEND = ("† chaotic: a seed's filter diverged (NEES above χ²(0.999) for good); its pairings then hinge on "
                  "the last bits of the arithmetic (the CPU's maths library and BLAS kernels), so the row's digits "
                  "may differ on another machine; rows without † reproduce to every digit")


def chaotic(diverged_seeds: float) -> bool:
    """Whether a leaderboard row is chaotic: at least one of its seeds' runs diverged."""
    return bool(np.isfinite(diverged_seeds) and diverged_seeds > 0)


def band_side(anees_value: float, lo: float, hi: float) -> str:
    """``"above"`` or ``"below"`` where an ANEES lies outside ``[lo, hi]``, else ``""`` (inside or
    NaN)."""
    if not all(np.isfinite(v) for v in (anees_value, lo, hi)):
        return ""
    return "above" if anees_value > hi else "below" if anees_value < lo else ""


def band_mark(anees_value: float, lo: float, hi: float) -> str:
    """``BAND_MARKS``' mark of where an ANEES lies against its band (``band_side``), "" inside."""
    return BAND_MARKS.get(band_side(anees_value, lo, hi), "")


def _last_estimated(frames: pd.DataFrame) -> pd.Series:
    """The last frame the estimator finished; all NaN when none."""
    done = frames[frames["map_size"].notna()] if "map_size" in frames else frames.iloc[:0]
    if len(done):
        return done.iloc[-1]
    return pd.Series({c: float("nan") for c in ("map_size", "duplicates", "false_landmarks", "map_rmse")})


def _count(value) -> float | int:
    """A count as an int, NaN where nothing was estimated."""
    return int(value) if np.isfinite(value) else float("nan")


def _smoothed(frames: pd.DataFrame, ate: float) -> float:
    """A smoother's final ATE (its last frame's ``ate_smoothed``); a filter's is its ATE."""
    value = frames["ate_smoothed"].iloc[-1] if "ate_smoothed" in frames else float("nan")
    return float(value) if np.isfinite(value) else ate


def loop_status(frames: pd.DataFrame) -> list[str]:
    """Why a closed-loop run cannot be trusted beyond the open loop's: an estimator that raised, or
    a pose covariance no longer positive definite (NEES NaN after frame 0 on a finished frame)."""
    lost = frames["error"].astype(str).str.startswith(ESTIMATOR_FAILED).to_numpy() if "error" in frames \
        else np.zeros(len(frames), bool)
    reasons = []
    if lost.any():
        at = int(frames["frame"].to_numpy()[lost.argmax()])
        reasons.append(f"the estimator failed at frame {at}, so no later frame was measured")
    nees = frames["nees"].to_numpy(dtype=float) if "nees" in frames else np.zeros(len(frames))
    bad = np.flatnonzero(~np.isfinite(nees[1:]) & ~lost[1:])
    return reasons + ([f"pose covariance not positive definite from frame {bad[0] + 1}"] if len(bad) else [])
