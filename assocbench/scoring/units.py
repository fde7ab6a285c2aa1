"""The unit of each summary and leaderboard column, in one place: ``run``'s table and the HTML
report (``harness/report``) print them."""

from __future__ import annotations

# ANEES is the mean NEES itself, not divided by the pose's dof: a consistent filter's is near the dof
ANEES_UNIT = "NEES (near the pose dof if consistent)"
# units of summary columns that do not end in one (``_ms``, ``_mm``, ``_deg``, ``_pct``, ``_s``)
UNITS = {"ate_rmse": "m", "ate_smoothed": "m", "map_rmse": "m", "surprisal_gap": "nats", "fps": "frames/s",
         "precision": "share", "recall": "share", "f1": "share", "precision_start": "share",
         "recall_start": "share", "perfect": "share of frames",
         "jc_share": "share of frames", "proven_optimal": "share of frames (NaN: not reported)",
         "true_mass": "probability (NaN: not a soft method)", "anees": ANEES_UNIT,
         "anees_lo": "NEES, low end of one run's 95 % band for anees",
         "anees_hi": "NEES, high end of one run's 95 % band for anees", "frames": "frames", "failures": "frames", "timed_out": "frames",
         "diverged_at": "frame (-1: never)", "icp_failures": "frames", "wrong_steps": "frames",
         "clutter_accepted": "features", "no_depth": "features", "map_size": "landmarks", "new_landmarks": "landmarks", "revisits": "re-sightings",
         "loop_closures": "re-sightings",
         "map_points": "points", "duplicates": "landmarks", "false_landmarks": "landmarks",
         "pair_precision": "share of sighting pairs", "pair_recall": "share of sighting pairs",
         "reference_landmarks": "landmarks"}
SUFFIX_UNITS = (("_ms", "ms"), ("_mm", "mm"), ("_deg", "deg"), ("_pct", "%"), ("_s", "s"))


def unit_of(metric: str) -> str:
    """The unit a summary column is printed in ("" where it is a plain count or a label)."""
    if metric in UNITS:
        return UNITS[metric]
    return next((unit for suffix, unit in SUFFIX_UNITS if metric.endswith(suffix)), "")
