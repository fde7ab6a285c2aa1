"""The ``Track`` core: what every track must say, in nine hooks. A track is one way of getting
frames and turning them into association problems (a simulated camera, a 2-D lidar, a recorded log);
the harness, CLI, ``list``, ``check``, leaderboard, report and Gymnasium envs ask it these and
nothing else:

==========================  ===================================================================
``name``, ``summary``       its registry name and one line for ``assocbench list``
``settings()``              its settings (``settings.Schema``): top-level keys and sections
``source(settings)``        its frame source for a run's checked ``Settings`` (``sources.base``)
``problem(source, k, run)`` frame ``k``'s ``(Problem, FrameTruth)``, built when asked for; a track
                            whose frames are not association problems implements the
                            ``OwnFrames`` capability instead (its own frame loop)
``columns(loop)``           its summary columns, in order, with the primary metric (name,
                            direction, unit) the report ranks by
``guards(loop)``            the summary columns ``assocbench check`` compares with a baseline
``suites()``                its shipped suites, name -> YAML path, and which ``check`` runs
``scenes()``                its shipped scenes or datasets, name -> one line
==========================  ===================================================================

Anything more is a capability (``tracks.capabilities``) the harness discovers and never assumes.
``FeatureTrack`` has the defaults of a track whose frames are ``Problem``s scored by the shared
metrics: such a track writes ``settings``, ``source``, ``problem``, ``suites`` and ``scenes``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..settings import Schema, Settings
from ..sources.base import FrameSource


@dataclass(frozen=True)
class Metric:
    """A summary column with its direction and unit: what the report ranks by."""

    name: str
    higher_better: bool
    unit: str = ""


@dataclass(frozen=True)
class Columns:
    """A track's summary columns: ``summary`` in the order ``run`` writes them, ``primary`` the
    metric the report ranks by, ``frames`` the per-frame columns a leaderboard keeps (its pictures
    read them), ``units`` of its own columns (shared ones: ``scoring.units``), and
    ``scored_against``: ``truth`` (a simulation's) or ``reference`` (a recorded dataset's own
    association), the word its pages use."""

    summary: tuple[str, ...]
    primary: Metric
    frames: tuple[str, ...] = ()
    units: Mapping[str, str] = field(default_factory=dict)
    scored_against: str = "truth"


@dataclass(frozen=True)
class GuardedMetric:
    """A column ``assocbench check`` guards: it may fall (``higher_better``) or rise by the suite's
    ``tolerance`` or ``ate_tolerance`` (times ``scale``, the tolerance's unit in this column's); a
    baseline value must lie in ``[lo, hi]``."""

    name: str
    higher_better: bool
    tolerance: str = "tolerance"     # or "ate_tolerance"
    scale: float = 1.0
    lo: float = 0.0
    hi: float = float("inf")
    required: bool = True            # False: compared only when the baseline has the column


@dataclass(frozen=True)
class SuiteFile:
    """A shipped suite: its YAML ``path``, and whether ``check`` runs it by default (``ci``) against
    ``results/baseline_<name>.csv``."""

    path: Path
    ci: bool = False


ACCURACY_GUARDS = tuple(GuardedMetric(m, True, hi=1.0) for m in ("precision", "recall", "f1", "perfect"))
ATE_GUARD = GuardedMetric("ate_rmse", False, "ate_tolerance")   # metres
# a smoother's final estimate of every pose (an iSAM2 back end; an EKF's equals ate_rmse), metres
SMOOTHED_ATE_GUARD = GuardedMetric("ate_smoothed", False, "ate_tolerance", required=False)
F1 = Metric("f1", True, "share")
ATE = Metric("ate_rmse", False, "m")


class Track:
    """One track: the nine hooks of the module docstring. Subclasses set ``name`` and ``summary``
    and implement the rest; ``register_track`` refuses one missing a hook."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""

    def settings(self) -> Schema:
        """Its settings beyond the common ones (``track``, ``scene``, ``frames``, ``seed``,
        ``method``, ``params``, ``loop``, ``time_limit_s``, ``limits``)."""
        raise NotImplementedError

    def source(self, settings: Settings) -> FrameSource:
        """The frame source of a run with these checked settings (cheap: frames are read later)."""
        raise NotImplementedError

    def columns(self, loop: bool) -> Columns:
        """Its summary columns and primary metric (``loop``: a closed-loop run's)."""
        raise NotImplementedError

    def guards(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """The summary columns ``check`` compares with a baseline."""
        raise NotImplementedError

    def suites(self) -> dict[str, SuiteFile]:
        """Its shipped suites: name -> ``SuiteFile``."""
        raise NotImplementedError

    def scenes(self) -> dict[str, str]:
        """Its shipped scenes or datasets: name -> one line (the first is its default)."""
        raise NotImplementedError

    # ``problem(source, k, run) -> (Problem, FrameTruth)``: declared by ``FeatureTrack`` and by any
    # track whose frames are association problems; a track that has its own frame loop instead
    # implements ``capabilities.OwnFrames``.


REQUIRED = ("settings", "source", "columns", "guards", "suites", "scenes")


class FeatureTrack(Track):
    """A track whose frames are ``Problem``s scored by the shared metrics, open loop and, with the
    ``ClosedLoop`` capability, closed (adding the trajectory columns)."""

    def problem(self, source: FrameSource, k: int, run: Any) -> tuple[Problem, FrameTruth]:
        """Frame ``k``'s problem and its truth (or a recorded track's reference)."""
        raise NotImplementedError

    def columns(self, loop: bool) -> Columns:
        from ..scoring.aggregate import SUMMARY_COLUMNS
        from ..scoring.loop_summary import LOOP_COLUMNS

        if loop:
            return Columns(SUMMARY_COLUMNS + LOOP_COLUMNS, ATE, LOOP_FRAME_COLUMNS)
        return Columns(SUMMARY_COLUMNS, F1, OPEN_FRAME_COLUMNS)

    def guards(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """Accuracy, and a closed loop's ATE."""
        return ACCURACY_GUARDS + ((ATE_GUARD,) if loop else ())


# the per-frame columns a feature track's leaderboard keeps: the runtime picture's, and a closed
# loop's trajectory, NEES and final map (its pictures)
OPEN_FRAME_COLUMNS = ("n", "m", "runtime_s")
LOOP_FRAME_COLUMNS = OPEN_FRAME_COLUMNS + ("pos_err", "rot_err_deg", "nees", "nees_dof", "est_x", "est_y", "est_z",
                                           "true_x", "true_y", "true_z", "odo_x", "odo_y", "final_map")


def loop_words(run: Any) -> str:
    """How a feature-track run was made: ``open loop``, or ``closed loop, <estimator> <mode>``."""
    return f"closed loop, {run.estimator.name} {run.estimator.mode}" if run.loop else "open loop"


def first_line(text: str | None) -> str:
    """The first paragraph of a docstring on one line (what ``list`` shows)."""
    return " ".join((text or "").strip().split("\n\n")[0].split())


def missing_hooks(track: Track) -> list[str]:
    """The core hooks ``track`` leaves out (``REQUIRED``, and ``problem`` or ``OwnFrames.records``)."""
    missing = [h for h in REQUIRED if getattr(type(track), h) is getattr(Track, h, None)]
    problem = getattr(type(track), "problem", None)
    if (problem is None or problem is FeatureTrack.problem) and not callable(getattr(track, "records", None)):
        missing.append("problem (or the OwnFrames capability's records)")
    return missing
