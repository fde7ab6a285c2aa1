"""What each leaderboard column means for the HTML report: label, unit (``scoring.units``), a
one-sentence meaning, better direction and digits. An unknown column (a newer harness, a plugin
track) is still shown under its CSV name, so nothing is dropped silently."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...scoring.units import unit_of
from ..loop_truth import REVISIT_GAP


@dataclass(frozen=True)
class Column:
    """One metric column. better: ``"high"``, ``"low"`` or ``""`` (a describing count); main: shown
    by default (others behind "more columns"), except in the suite kinds of ``minor_in``; count: a
    whole number per run, so a whole mean prints without decimals; ``lo``, ``hi``: a run's possible
    values, checked when a CSV is read."""

    key: str
    label: str
    meaning: str
    better: str = ""
    digits: int = 3
    main: bool = True
    minor_in: tuple[str, ...] = ()
    count: bool = False
    lo: float = 0.0
    hi: float = math.inf

    def shown(self, kind: str) -> bool:
        """Whether the column is shown by default on a page of a ``kind`` suite."""
        return self.main and kind not in self.minor_in

    @property
    def unit(self) -> str:
        """The unit without ``unit_of``'s note on NaN (the cell says n/a instead)."""
        return unit_of(self.key).split(" (")[0]

    @property
    def header(self) -> str:
        """The label with its unit in brackets, e.g. ``ATE [m]``."""
        return f"{self.label} [{self.unit}]" if self.unit else self.label


CATALOGUE = (
    Column("f1", "F1", "harmonic mean of precision and recall over all pairings (micro average)", "high",
           minor_in=("loop",), hi=1.0),
    Column("precision", "precision", "returned pairings that are true / all returned pairings", "high", hi=1.0),
    Column("recall", "recall", "true pairings returned / all true pairings", "high", hi=1.0),
    Column("perfect", "perfect frames", "share of frames associated exactly as the truth (one bad pairing can "
           "wreck a filter)", "high", minor_in=("loop",), hi=1.0),
    Column("surprisal_gap", "surprisal gap", "mean over frames of the total surprisal of the returned association "
           "minus that of the true one; negative: the method found a likelier explanation than the truth",
           "low", 2, minor_in=("loop",), lo=-math.inf),
    Column("ate_rmse", "ATE", "RMSE of the position error of each frame's pose as the estimator had it then, no "
           "alignment (as evo_ape)", "low", 4),
    Column("ate_mm", "ATE", "RMSE of the positions tracked by ICP against the truth, no alignment", "low", 1),
    Column("rot_rmse_deg", "rotation RMSE", "RMSE of the heading / rotation error of each frame's pose", "low", 3),
    Column("anees", "ANEES", "mean over frames of the pose NEES (not divided by the dof); a consistent filter's is "
           "near the pose's degrees of freedom (6 in space, 3 in the plane), inside the band", "", 2),
    Column("ate_smoothed", "ATE smoothed", "ATE of a smoother's final estimate of every pose (iSAM2; equal to ATE "
           "for a filter)", "low", 4, main=False),
    Column("runtime_median_ms", "runtime median", "median wall time of one call of the method's associate()", "low", 2),
    Column("proven_optimal", "proven optimal", "share of frames whose answer the method proved optimal (JCBB, "
           "CCDA; n/a for methods that make no such claim)", "high", main=False, hi=1.0),
    Column("true_mass", "true mass", "mean probability a soft method (JPDA) puts on each candidate's true "
           "outcome; n/a for hard methods", "high", main=False, hi=1.0),
    Column("duplicates", "duplicates", "landmarks mapped twice in the final map (SLAM mode)", "low", 2),
    Column("false_landmarks", "false landmarks", "map entries with no true landmark behind them", "low", 2),
    Column("map_rmse", "map RMSE", "RMSE of the final map's landmark positions", "low", 4),
    Column("map_size", "map size", "landmarks in the final map", "", 1, main=False),
    Column("pair_precision", "pair precision", "of the pairs of sightings the method put on one landmark, the share "
           "the reference says are one (a wrong merge lowers it)", "high"),
    Column("pair_recall", "pair recall", "of the pairs of sightings the reference says are one landmark, the share "
           "the method put on one (a duplicate landmark lowers it)", "high"),
    Column("reference_landmarks", "reference landmarks", "landmarks of the dataset's reference its frames sighted "
           "(what map size is compared with)", "", 1, main=False),
    Column("new_landmarks", "new landmarks", "landmarks the method's decisions added to the map", "", 1, main=False),
    Column("no_depth", "no depth", "features that could not be initialised (no triangulation depth)", "", 1,
           main=False),
    Column("revisits", "revisits", f"landmarks measured again after {REVISIT_GAP} frames or more unseen (summed over frames)", "", 1, main=False),
    Column("loop_closures", "loop closures", "revisits paired with the landmark's old map entry (closing the loop)", "high", 1,
           main=False),
    Column("precision_start", "precision at start", "precision of ICP's first iteration, from the previous pose",
           "high", hi=1.0),
    Column("recall_start", "recall at start", "recall of ICP's first iteration", "high", main=False, hi=1.0),
    Column("icp_failures", "ICP failures", "frames whose ICP reported failure (pose held, frame not fused; a method "
           "that raised or hung is a failed frame instead)", "low", 1,
           count=True),
    Column("wrong_steps", "wrong steps", "steps ICP accepted more than 20 mm off the true step (a silent failure)",
           "low", 1, count=True),
    Column("ate_deg", "rotation ATE", "RMSE of the rotation error of the tracked poses", "low", 3, main=False),
    Column("final_drift_mm", "final drift", "position error of the last frame", "low", 1),
    Column("step_error_mm", "step error", "RMS relative position error of one frame's step", "low", 2, main=False),
    Column("step_error_deg", "step rotation error", "RMS relative rotation error of one frame's step", "low", 3,
           main=False),
    Column("map_points", "map points", "points in the fused map", "", 0, main=False),
    Column("compression_pct", "compression", "map points / (frames x pixels of the downsampled input)", "low", 2,
           main=False),
    Column("map_median_mm", "map error median", "median distance of the map's points to the true surfaces", "low", 1),
    Column("map_p95_mm", "map error p95", "95th percentile of that distance", "low", 1, main=False),
    Column("icp_ms", "ICP time", "median wall time of one frame's ICP (frames whose method call failed left out)",
           "low", 1),
    Column("fusion_ms", "fusion time", "median wall time of one frame's fusion", "low", 1, main=False),
    Column("fps", "throughput", "frames tracked and fused per second (frames whose method call failed left out)",
           "high", 1, main=False),
)
BY_KEY = {c.key: c for c in CATALOGUE}

# columns that say how a row was measured, not how well: shown in their own way (counts "k / n",
# the status) or not at all (the ANEES band is a column of its own; per-seed bookkeeping)
COUNT_COLUMNS = {"timed_out": ("timed out", "frames where the method spent its search budget and returned its best "
                               "hypothesis so far"),
                 "failures": ("failed", "frames where the method raised, returned an invalid association, overran its time limit "
                              "or its worker died"),
                 "diverged": ("diverged", "seeds whose NEES stayed above the chi-square 0.999 bound for 5 frames; a "
                              "row with one is chaotic: its pairings then hinge on the last bits of the arithmetic, "
                              "so its digits may differ on another machine")}
NOT_METRICS = {"scenario", "method", "status", "seeds", "frames", "seed", "scene", "difficulty", "error", "anees_lo",
               "anees_hi", "diverged_at", "jc_share", "clutter_accepted", "runtime_p95_ms", *COUNT_COLUMNS}


# the ranges of the columns that are not metrics (``Column.lo``, ``hi``): counts, and the ANEES band
RANGES = {"seeds": (1, math.inf), "frames": (1, math.inf), "seed": (0, math.inf), "diverged_at": (-1, math.inf),
          "jc_share": (0, 1), **{k: (0, math.inf) for k in ("anees_lo", "anees_hi", "clutter_accepted",
                                                           "runtime_p95_ms", *COUNT_COLUMNS)}}
WHOLE = ("seeds", "frames", "seed")   # columns whose every value is a whole number


def value_range(key: str) -> tuple[float, float]:
    """The values column ``key`` of a leaderboard CSV can hold (NaN aside: no value): a metric's
    ``lo``..``hi``, a spread (``_std``) at least 0, an unknown column any finite number."""
    if key in BY_KEY:
        return BY_KEY[key].lo, BY_KEY[key].hi
    if key.endswith("_std"):
        return 0.0, math.inf
    return RANGES.get(key, (-math.inf, math.inf))


def column(key: str) -> Column:
    """The catalogue's column, or one named after the CSV's column for a key it does not know."""
    return BY_KEY.get(key) or Column(key, key.replace("_", " "), "a column this report does not describe", "", 3,
                                     main=False)
