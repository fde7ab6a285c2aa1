"""Summary of a closed-loop run from its per-frame records (``harness.loop``).

ate_rmse (m) and rot_rmse_deg: RMSE of the position and rotation errors over all frames, no
alignment (``evo_ape tum truth.txt estimate.txt`` gives the same), each frame's pose as the
estimator had it then; ate_smoothed (m): the ATE of a smoother's final estimate of every pose
(iSAM2; a filter revises no past pose, so its ate_smoothed is its ate_rmse); anees: mean pose
NEES over the frames with a pose covariance (slam's frame 0 has none), with the two-sided 95 %
band ``[anees_lo, anees_hi] = χ²_{qN}(0.025, 0.975) / N``, q the pose's degrees of freedom (the
frames' ``nees_dof``: 6 for a pose in space, 3 for one in the plane). The band assumes independent frames; the
frames of one run are correlated (the same map error steers them all), so one run's ANEES
scatters more widely than the band says. diverged_at: the first frame whose NEES stays above
χ²_q(0.999) for 5 frames, -1 for never. Map figures are the last frame's: confirmed landmarks,
duplicates, false landmarks and map_rmse (m) of the entries tied to a landmark. ``revisits`` and
``loop_closures`` are summed over frames (``harness.loop_truth.RevisitCounter``).
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
    """``"above"`` or ``"below"`` where an ANEES lies outside its band ``[lo, hi]``, else ``""``
    (inside, or any of them NaN)."""
    if not all(np.isfinite(v) for v in (anees_value, lo, hi)):
        return ""
    return "above" if anees_value > hi else "below" if anees_value < lo else ""


def band_mark(anees_value: float, lo: float, hi: float) -> str:
    """``BAND_MARKS``' mark of where an ANEES lies against its band (``band_side``), "" inside."""
    return BAND_MARKS.get(band_side(anees_value, lo, hi), "")


def _last_estimated(frames: pd.DataFrame) -> pd.Series:
    """The last frame the estimator finished (its map columns); all NaN when it finished none
    (a run whose estimator failed at its start)."""
    done = frames[frames["map_size"].notna()] if "map_size" in frames else frames.iloc[:0]
    if len(done):
        return done.iloc[-1]
    return pd.Series({c: float("nan") for c in ("map_size", "duplicates", "false_landmarks", "map_rmse")})


def _count(value) -> float | int:
    """A count as an int, NaN where nothing was estimated."""
    return int(value) if np.isfinite(value) else float("nan")


def _smoothed(frames: pd.DataFrame, ate: float) -> float:
    """ATE of a smoother's final trajectory (its last frame's ``ate_smoothed``); a filter does not
    revise past poses, so its smoothed ATE is its ATE."""
    value = frames["ate_smoothed"].iloc[-1] if "ate_smoothed" in frames else float("nan")
    return float(value) if np.isfinite(value) else ate


def loop_status(frames: pd.DataFrame) -> list[str]:
    """Reasons a closed-loop run cannot be trusted beyond the open loop's: an estimator that raised
    (its frames from then on were not measured), a pose covariance that stopped being positive
    definite (NEES NaN after frame 0, on a frame the estimator finished)."""
    lost = frames["error"].astype(str).str.startswith(ESTIMATOR_FAILED).to_numpy() if "error" in frames \
        else np.zeros(len(frames), bool)
    reasons = []
    if lost.any():
        at = int(frames["frame"].to_numpy()[lost.argmax()])
        reasons.append(f"the estimator failed at frame {at}, so no later frame was measured")
    nees = frames["nees"].to_numpy(dtype=float) if "nees" in frames else np.zeros(len(frames))
    bad = np.flatnonzero(~np.isfinite(nees[1:]) & ~lost[1:])
    return reasons + ([f"pose covariance not positive definite from frame {bad[0] + 1}"] if len(bad) else [])
