"""The summary row of a dense run, and its status: not ok only when nothing could be measured. ICP
losing track (``icp_failures``) and accepting a wrong pose (``wrong_steps``: more than
``WRONG_STEP_MM`` off the true step) are the method's results, counted.

    ate_mm       = sqrt(mean_k |p̂_k − p_k|²)          (no alignment: frame 0's pose is given)
    step_error   = RMS over k of the relative pose error of the step k−1 → k
    compression  = map points / (frames · w · h)        (against concatenating the downsampled frames)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...scoring.aggregate import OK
from ...scoring.trajectory import ate_rmse, rotation_rmse_deg


def poses(frames: pd.DataFrame, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, 3, 3) and positions (N, 3) of the ``<prefix>x, y, z, qx, qy, qz, qw`` columns."""
    from scipy.spatial.transform import Rotation

    p = frames[[f"{prefix}{c}" for c in "xyz"]].to_numpy(float)
    q = frames[[f"{prefix}q{c}" for c in "xyzw"]].to_numpy(float)
    return Rotation.from_quat(q).as_matrix(), p


def _rms(values: pd.Series) -> float:
    v = values.dropna().to_numpy(float)
    return float(np.sqrt(np.mean(v ** 2))) if len(v) else float("nan")


def _mean(frames: pd.DataFrame, col: str) -> float:
    v = frames[col].dropna() if col in frames else pd.Series(dtype=float)
    return float(v.mean()) if len(v) else float("nan")


# an accepted ICP step this far from the true step (relative pose error) is a wrong pose passed as
# good: accepted steps measured at most 6.8 mm over 200 frames of bays and crates (frame-to-model
# and from true poses), while ICP sliding along bare walls (kdtree on room) accepted 69-105 mm
WRONG_STEP_MM = 20.0

# the ``icp_reason`` of a frame whose method call failed (it raised, hung, exited or could not be built): its pose held
METHOD_FAILED = "the method failed"


def wrong_accepted(frames: pd.DataFrame) -> int:
    """Steps ICP accepted with an error above ``WRONG_STEP_MM``, except those right after a failed
    frame."""
    failed = frames["icp_failed"].astype(bool)
    after_ok = ~failed.shift(1, fill_value=True)   # frame 0 has no step
    error = frames["step_error_mm"] if "step_error_mm" in frames else pd.Series(np.nan, index=frames.index)
    return int(((~failed) & after_ok & (error > WRONG_STEP_MM)).sum())


def icp_failures(frames: pd.DataFrame) -> int:
    """Tracked frames whose ICP failed (a failed method call is held too but counts in
    ``failures``)."""
    tracked = frames[frames["frame"] > 0]
    errored = tracked["error"].fillna("").ne("") if "error" in tracked else False
    return int((tracked["icp_failed"].astype(bool) & ~errored).sum())


def dense_status(frames: pd.DataFrame) -> str:
    """``ok``, or why the numbers cannot be trusted: the method failed, or no correspondence in any
    frame."""
    tracked = frames[frames["frame"] > 0]
    failed = int((tracked["error"] != "").sum()) if "error" in tracked else 0
    if failed:
        return f"{failed}/{len(tracked)} frames failed"
    if len(tracked) and tracked.get("pairs", pd.Series(0, index=tracked.index)).fillna(0).sum() == 0:
        return "no correspondences in any frame"
    return OK


def _last(frames: pd.DataFrame, col: str) -> float:
    """An end-of-run fact (``run.run_end``): the last record's ``col``, NaN when absent."""
    return float(frames[col].iloc[-1]) if col in frames and len(frames) else float("nan")


# the method's work a frame, the time ``fps`` divides by: the model's prediction (the splat into
# the view), ICP and fusion; the sensor's simulation (the depth frame) and the scoring are not the method's.
# Over the frames whose method call did not fail, as ``icp_ms``: NaN when no tracked frame's did
METHOD_SECONDS = ("predict_s", "icp_s", "fusion_s")


def summarize_dense(frames: pd.DataFrame) -> dict:
    """The summary row (``DENSE_COLUMNS``) of a run's per-frame records; the map's facts are the
    last record's (``run.run_end``)."""
    frames = frames.sort_values("frame")
    R_true, p_true = poses(frames, "true_")
    R_est, p_est = poses(frames, "est_")
    tracked = frames[frames["frame"] > 0]
    # a failed method call's time (it raised at once, or hung until killed) is not ICP's: left out
    called = frames[frames["error"].fillna("") == ""] if "error" in frames else frames
    ms = lambda col: 1000 * float(called[col].dropna().median()) if col in called and called[col].notna().any() \
        else float("nan")  # noqa: E731
    seconds = called[[c for c in METHOD_SECONDS if c in called]].fillna(0).to_numpy().sum()
    measured = seconds > 0 and (called["frame"] > 0).any()
    return {
        "frames": len(frames), "status": dense_status(frames),
        "failures": int((frames["error"] != "").sum()) if "error" in frames else 0,
        "precision": _mean(tracked, "precision"), "recall": _mean(tracked, "recall"),
        "precision_start": _mean(tracked, "precision_start"), "recall_start": _mean(tracked, "recall_start"),
        "icp_failures": icp_failures(frames), "wrong_steps": wrong_accepted(frames),
        "ate_mm": 1000 * ate_rmse(p_true, p_est), "ate_deg": rotation_rmse_deg(R_true, R_est),
        "final_drift_mm": 1000 * float(np.linalg.norm(p_est[-1] - p_true[-1])),
        "step_error_mm": _rms(tracked["step_error_mm"]) if "step_error_mm" in tracked else float("nan"),
        "step_error_deg": _rms(tracked["step_error_deg"]) if "step_error_deg" in tracked else float("nan"),
        "map_points": int(frames["map_points"].iloc[-1]), "compression_pct": _last(frames, "compression_pct"),
        "map_median_mm": _last(frames, "map_median_mm"), "map_p95_mm": _last(frames, "map_p95_mm"),
        "icp_ms": ms("icp_s"), "fusion_ms": ms("fusion_s"),
        "fps": len(called) / seconds if measured else float("nan"),
    }
