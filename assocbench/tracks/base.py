"""The ``Track`` interface and the registry of tracks.

A track is one way of sensing the scene with its own measurement model: the camera (pixels),
the planar lidar (posts in range-bearing), the lines (walls as ``(α, r)``), the dense depth
camera. Each is the same pipeline with other parts plugged in, so a track says what it
contributes and the harness, the CLI, ``list``, ``check``, the leaderboard and the Gymnasium
envs ask the registry instead of switching on the track's name:

* ``claims_scene`` / ``claims_method``: which runs are its own (a scene's naming convention; a
  method only it has, such as the dense track's projective association);
* ``config_sections``: its settings, with their defaults (the run config's schema is the union);
* ``sequence_spec`` / ``load_sequence``: what determines its simulated sequence, and the sequence;
* ``problems``: the open loop's ``(Problem, FrameTruth)`` of every frame; a track whose frames
  are not a ``Problem`` (the dense track: ICP on depth frames) yields its own records instead
  (``frame_records``), calling the method through the harness's ``MethodCalls``, so time limits,
  worker isolation and resume hold for it too;
* ``run_settings``, ``summarize``, ``summary_columns``: its own typed sections of a run, and
  the summary row of a run's records;
* ``make_estimator`` / ``loop_sensor``: the closed loop's estimator at frame 0 and what it reads;
* ``shipped_scenes`` / ``trajectories``: what ``assocbench list`` shows for it;
* ``landmarks`` / ``map_figure``: the leaderboard's top view of a scene;
* ``frame_picture`` / ``run_pictures`` (where ``pictures`` is set): what ``assocbench frame`` and
  ``assocbench render`` draw; ``pictures_elsewhere`` says where a track without them shows its runs;
* ``ci_suites`` and ``suites``: its shipped suites; ``assocbench check`` guards the CI ones;
* ``gym_modes`` / ``gym_envs`` / ``env_slots``: its Gymnasium envs (``assocbench.gymenv``
  registers every track's ids) and the padded sizes of their observations and actions.

Built-in tracks register here; a third party's track registers through the entry-point group
``assocbench.tracks`` (a ``Track`` subclass or an instance), or by a module that calls
``register_track`` when imported, named in the environment variable ``ASSOCBENCH_TRACKS``
(``pkg.mod[,pkg.mod2]``): a track that is not installed. The variable is read whenever the
registry is asked, so it reaches every process that runs a job: worker processes (forked or
forkserver's, which get the leader's environment), and dask workers where it is set.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass
from functools import lru_cache
from importlib import import_module, metadata
from pathlib import Path
from typing import Any, ClassVar, NamedTuple, Protocol

import mujoco
import numpy as np

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..errors import UserError
from ..scoring.aggregate import SUMMARY_COLUMNS, leaderboard_table, summarize
from ..scoring.loop_summary import LOOP_COLUMNS
from ..sim.scene import LANDMARK_PREFIX, WALL_PREFIX, mjcf_error, resolve_scene_path

ENTRY_POINT_GROUP = "assocbench.tracks"
MODULES_VARIABLE = "ASSOCBENCH_TRACKS"   # modules that register a track when imported


@dataclass(frozen=True)
class SceneMarks:
    """What a scene's MJCF names, read without compiling it: ``lm*`` sites (camera landmarks),
    ``lm*`` geoms (posts) and ``lw*`` geoms (map walls). Tracks claim scenes by these."""

    path: Path
    landmark_sites: int
    landmark_geoms: int
    wall_geoms: int


@dataclass(frozen=True)
class GuardedMetric:
    """A summary column ``assocbench check`` guards: it may fall (``higher_better``) or rise by the
    suite's ``tolerance`` or ``ate_tolerance`` (times ``scale``: the tolerance's unit in this
    column's), and a baseline value must lie in ``[lo, hi]``."""

    name: str
    higher_better: bool
    tolerance: str = "tolerance"     # or "ate_tolerance"
    scale: float = 1.0
    lo: float = 0.0
    hi: float = float("inf")
    required: bool = True            # False: compared only when the baseline has the column


@dataclass(frozen=True)
class GymEnv:
    """One Gymnasium env a track offers: its ``id`` (``assocbench/<Scene>-v0``, ``<Scene>Loop-v0``
    for the closed loop), the ``scene`` it runs and whether it is the closed ``loop``."""

    id: str
    scene: str
    loop: bool = False


class EnvSlots(NamedTuple):
    """The padded sizes of a track's Gymnasium env: ``landmarks`` (N) candidate slots and
    ``features`` (M) feature slots, bounds no frame of the run exceeds whatever the seed, and
    ``dim`` (d) the measurement's dimension."""

    landmarks: int
    features: int
    dim: int = 2


ACCURACY_GUARDS = tuple(GuardedMetric(m, True, hi=1.0) for m in ("precision", "recall", "f1", "perfect"))
ATE_GUARD = GuardedMetric("ate_rmse", False, "ate_tolerance")   # metres
# a smoother's final estimate of every pose (the iSAM2 back end; an EKF's equals ate_rmse), metres
SMOOTHED_ATE_GUARD = GuardedMetric("ate_smoothed", False, "ate_tolerance", required=False)


@dataclass(frozen=True)
class RunFrame:
    """One frame of a recorded run, rebuilt for its picture (``assocbench render``): the ``problem``
    the method was given and its ``truth``, the recorded ``association`` (n,) (all −1 on a failed
    frame) and ``error`` ("" when it succeeded), the run's ``record`` of the frame (a row of its
    frames table), and in the closed loop the ``estimator`` after the frame's update (live: valid
    until the next frame is replayed; None in the open loop)."""

    k: int
    problem: Problem
    truth: FrameTruth
    association: np.ndarray
    error: str
    record: dict
    estimator: Any = None


class MethodCalls(Protocol):
    """The plugin boundary a track's own frame loop calls its method through (the harness
    implements it): each call is announced to the supervising process, timed, and anything it
    raises becomes that frame's ``error``. ``faults`` maps frames already known failed (a call
    that hung or killed its worker) to ``(error, runtime_s)``; ``WARM_UP`` (-1): the method could
    not even be built."""

    faults: dict

    def build(self, make: Callable[[], Any]) -> tuple[Any | None, str]:
        """``(make(), "")``, or ``(None, error)`` when building the method failed."""

    def call(self, k: int, fn: Callable[[], Any]) -> tuple[Any | None, float, str]:
        """``(fn(), seconds, "")`` for frame ``k``, or ``(None, seconds, error)``."""


class Track:
    """One track of the benchmark. Subclasses set the class attributes and override the
    methods their track has; a method left as it is raises a ``UserError`` saying the track
    has no such part (e.g. a track without a closed loop)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    ci_suites: ClassVar[tuple[str, ...]] = ()   # shipped suites `assocbench check` runs by default
    suites: ClassVar[tuple[str, ...]] = ()       # its shipped suites (configs/<name>.yaml)
    pictures: ClassVar[bool] = False              # `frame` and `render` serve it (frame_picture, run_pictures)
    renders_frames: ClassVar[bool] = False        # sequences are MuJoCo GL images: the envs' render_mode draws them, no fork after
    pictures_elsewhere: ClassVar[str] = ""        # without pictures: where its runs are seen instead
    fallback: ClassVar[bool] = False              # claims every scene no other track claims
    spec_type: ClassVar[type | None] = None       # the class of its sequence specs
    has_problems: ClassVar[bool] = True           # frames are Problems (else: frame_records)
    gym_modes: ClassVar[tuple[str, ...]] = ()     # its Gymnasium envs per shipped scene: "open", "loop"

    # --- which runs are its own ---------------------------------------------------------
    def claims_scene(self, marks: SceneMarks) -> bool:
        """Whether the scene with ``marks`` follows this track's naming convention."""
        return False

    def claims_method(self, method: str) -> bool:
        """Whether ``method`` exists on this track only (it then implies the track)."""
        return False

    # --- settings and sequence ------------------------------------------------------------
    def section_types(self) -> dict[str, type]:
        """This track's settings sections as dataclasses that check their values when built
        (``{"lidar": LidarConfig}``); every run checks them, used by its track or not."""
        return {}

    def config_sections(self) -> dict[str, dict]:
        """This track's settings sections and their defaults (``{"lidar": {...}}``): by default
        those of ``section_types``; a plugin may give plain mappings instead."""
        return {name: asdict(cls()) for name, cls in self.section_types().items()}

    def sequence_spec(self, cfg: dict, estimator: Any) -> Any:
        """The spec of the run's sequence from the merged, checked config ``cfg``: a picklable
        value (it travels to worker processes) with ``scene`` (str) and ``resolved_trajectory()``
        (str), which ``run`` names its output by; the sequence it loads has ``track`` (this name)."""
        raise self._missing("a sequence")

    def load_sequence(self, spec: Any, cache_dir: Path | None = None, use_cache: bool = True) -> Any:
        """The sequence of ``spec`` (from the cache when there is one)."""
        raise self._missing("a sequence")

    def cache_folder(self) -> str:
        """The subfolder of the cache folder that ``load_sequence`` stores into (its name unless
        it says otherwise); the CLI checks it is not a file before a run compiles or renders."""
        return self.name

    def problems(self, seq: Any, belief: Any, seed: int) -> list:
        """The open loop's ``(Problem, FrameTruth)`` of every frame of ``seq``."""
        raise self._missing("open-loop problems")

    def run_settings(self, cfg: dict) -> tuple:
        """Its typed settings sections a run needs beyond the sequence (``RunSpec.settings``)."""
        return ()

    def check_method(self, method: str, params: dict, loop: bool) -> None:
        """Refuse a method this track cannot run, or bad parameters (the harness builds feature
        associators itself; a track with its own kind of method checks it here)."""

    def frame_records(self, seq: Any, spec: Any, calls: MethodCalls, first: int = 0,
                      artifacts: Path | None = None) -> Iterator[dict]:
        """Per-frame records from frame ``first`` on, for a track whose frames are not a
        ``Problem``; the method is called through ``calls``. ``artifacts``: a folder for the
        run's end-of-run files (``run`` keeps them), or None."""
        raise self._missing("frame records of its own")

    def summarize(self, frames: Any) -> dict:
        """The summary row of a run's per-frame records (the feature tracks' by default)."""
        return summarize(frames)

    def summary_columns(self, loop: bool) -> tuple[str, ...]:
        """The summary's columns, in the order ``run`` prints and writes them."""
        return SUMMARY_COLUMNS + (LOOP_COLUMNS if loop else ())

    def check_metrics(self, loop: bool) -> tuple[GuardedMetric, ...]:
        """The columns ``check`` compares with a baseline: accuracy, and a closed loop's ATE."""
        return ACCURACY_GUARDS + ((ATE_GUARD,) if loop else ())

    def leaderboard_table(self, summaries: Any) -> Any:
        """One row per scenario × method from the runs' summaries (mean over seeds)."""
        return leaderboard_table(summaries)

    def write_leaderboard(self, summaries: Any, frames: Any, out: Path) -> dict | None:
        """Write the track's own leaderboard files (``{"md": path, ...}``, all or none), or None
        for the harness's (CSV, Markdown, plots)."""
        return None

    def warm_up(self) -> None:
        """Load (or compile, announced on stderr) the track's own compiled kernels, once, in the
        process the workers are forked from, so no frame's time includes a compile."""

    def ci_suite_skipped(self, name: str) -> str | None:
        """Why the CI suite ``name`` cannot run here (an optional package missing), or None."""
        return None

    def run_labels(self, spec: Any) -> dict:
        """Columns that say how a run was made, beside its summary (the closed loop's mode)."""
        return {"loop": spec.estimator.mode if spec.loop else "open"}

    def describe_run(self, spec: Any) -> str:
        """How a run was made, in words for its header (``open loop``; ``closed loop, ekf slam``)."""
        return f"closed loop, {spec.estimator.name} {spec.estimator.mode}" if spec.loop else "open loop"

    def run_writers(self, frames: Any, artifacts: Path, out: Path, title: str) -> dict:
        """Writers of the track's own files of one run (``{path: write(path)}``), from its frames and
        the end-of-run files its worker left in ``artifacts``; written with the CSVs, all or none."""
        return {}

    # --- closed loop ----------------------------------------------------------------------
    def make_estimator(self, seq: Any, cfg: Any, belief: Any, seed: int) -> Any:
        """The closed loop's estimator at frame 0."""
        raise self._missing("a closed loop")

    def loop_sensor(self, seq: Any, belief: Any, est: Any, seed: int) -> Any:
        """What the closed loop reads from ``seq``: measurements, odometry, pose columns."""
        raise self._missing("a closed loop")

    # --- what a user sees -----------------------------------------------------------------
    def shipped_scenes(self) -> dict[str, str]:
        """Its shipped scenes: name -> one-line description."""
        return {}

    def trajectories(self) -> list[tuple[str, str]]:
        """Its named trajectories: (name, one-line description)."""
        return []

    def landmarks(self, scene: str) -> Any:
        """The true landmarks of ``scene`` for the leaderboard's map views."""
        raise self._missing("landmarks")

    def map_figure(self, frames: Any, scene: str, title: str) -> Any:
        """The leaderboard's top view of ``scene`` from the closed-loop ``frames`` of one seed, or
        None for the default view (true path, estimates and final maps over ``landmarks``)."""
        return None

    def frame_picture(self, spec: Any, index: int) -> tuple[np.ndarray, str]:
        """``assocbench frame``: frame ``index`` of the run ``spec``'s sequence with its truth drawn,
        as an RGB image (H, W, 3) uint8, and one line of what the frame holds and what the marks mean."""
        raise self._missing("pictures of single frames")

    def run_pictures(self, spec: Any, seq: Any, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
        """``assocbench render``: one RGB picture (H, W, 3) uint8 per recorded frame, all of one
        size, showing what the method decided on ``seq`` (the run's sequence)."""
        raise self._missing("pictures of a run")

    # --- Gymnasium envs -------------------------------------------------------------------
    def gym_envs(self) -> tuple[GymEnv, ...]:
        """Its Gymnasium envs: for each shipped scene and each of ``gym_modes``, the id
        ``assocbench/<Scene>-v0`` (``open``) or ``assocbench/<Scene>Loop-v0`` (``loop``), the
        scene's name in CamelCase (``post_grid`` -> ``PostGrid``)."""
        suffix = {"open": "", "loop": "Loop"}
        camel = {scene: "".join(part.capitalize() for part in scene.split("_")) for scene in self.shipped_scenes()}
        return tuple(GymEnv(f"assocbench/{name}{suffix[mode]}-v0", scene, mode == "loop")
                     for scene, name in camel.items() for mode in self.gym_modes)

    def env_slots(self, spec: Any) -> EnvSlots:
        """The padded sizes of its Gymnasium env for the ``RunSpec`` ``spec``: candidate slots for
        the scene's map (the closed loop's slam adds the map's cap) and feature slots."""
        raise self._missing("Gymnasium env")

    def owns_spec(self, spec: Any) -> bool:
        """Whether ``spec`` is a sequence spec of this track."""
        return self.spec_type is not None and isinstance(spec, self.spec_type)

    def _missing(self, what: str) -> UserError:
        return UserError(f"the {self.name} track has no {what}")


_TRACKS: dict[str, Track] = {}
_BUILTINS = ("camera", "planar", "lines", "dense")


def register_track(track: Track | type[Track]) -> Track:
    """Add ``track`` (a ``Track`` subclass or instance) to the registry; a name taken by
    another track is a ``UserError``."""
    inst = track() if isinstance(track, type) else track
    if not isinstance(inst, Track) or not inst.name:
        raise UserError(f"{track!r} is not a Track with a name: subclass assocbench.tracks.base.Track")
    other = _TRACKS.get(inst.name)
    if other is not None and type(other) is not type(inst):
        raise UserError(f"track name {inst.name!r} is taken by {type(other).__module__}; choose another name")
    _TRACKS[inst.name] = inst
    return inst


@lru_cache(maxsize=1)
def _load_builtins_and_plugins() -> None:
    for name in _BUILTINS:
        import_module(f"assocbench.tracks.{name}.track")
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            register_track(ep.load())
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - a broken plugin is named, not a traceback
            raise UserError(f"track plugin {ep.name!r} ({ep.value}) failed to load: "
                            f"{type(exc).__name__}: {exc}") from None


def _load_named_modules() -> None:
    """Import each module named in ``ASSOCBENCH_TRACKS`` (comma-separated); importing one
    registers its track. Read on every call, not once: a worker process sets the leader's
    environment after the registry may already have been asked (a forkserver's preload)."""
    for name in filter(None, (n.strip() for n in os.environ.get(MODULES_VARIABLE, "").split(","))):
        if name in sys.modules:
            continue
        try:
            import_module(name)
        except Exception as exc:  # noqa: BLE001 - a broken module is named in one line
            raise UserError(f"track module {name!r} named in {MODULES_VARIABLE} failed to import: "
                            f"{type(exc).__name__}: {exc} (is its folder on PYTHONPATH?)") from None


def tracks() -> dict[str, Track]:
    """Every registered track by name: the built-ins first in their own order (``_BUILTINS``), then
    plugins and the modules named in ``ASSOCBENCH_TRACKS`` in the order they registered. A
    built-in's module imported before the registry was asked registers first, so the order is
    fixed here, not left to the imports (``check`` runs its suites, and names the first missing
    baseline, in this order)."""
    _load_builtins_and_plugins()
    _load_named_modules()
    ordered = {name: _TRACKS[name] for name in _BUILTINS if name in _TRACKS}
    return ordered | {name: track for name, track in _TRACKS.items() if name not in ordered}


def get_track(name: str) -> Track:
    """The registered track called ``name``."""
    known = tracks()
    if name not in known:
        raise UserError(f"unknown track {name!r}: choose one of {', '.join(known)}")
    return known[name]


def iter_tracks() -> Iterator[Track]:
    """The registered tracks, built-ins first in their own order (``tracks``)."""
    return iter(tracks().values())


def track_of_spec(spec: Any) -> Track:
    """The track whose sequence spec ``spec`` is."""
    for track in iter_tracks():
        if track.owns_spec(spec):
            return track
    raise UserError(f"no registered track makes sequences of {type(spec).__name__}")


def first_line(text: str | None) -> str:
    """The first paragraph of a docstring on one line (what ``list`` shows)."""
    return " ".join((text or "").strip().split("\n\n")[0].split())


def scene_marks(scene: str | Path) -> SceneMarks:
    """Count what the scene's MJCF names (parsed, not compiled; one-line error for bad XML)."""
    path = resolve_scene_path(scene)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except (ValueError, RuntimeError) as exc:
        raise mjcf_error(path, exc) from None

    def named(items, prefix: str) -> int:
        return sum(1 for item in items if item.name.startswith(prefix))

    return SceneMarks(path, named(spec.sites, LANDMARK_PREFIX), named(spec.geoms, LANDMARK_PREFIX),
                      named(spec.geoms, WALL_PREFIX))


def track_for_scene(scene: str | Path) -> Track:
    """The track whose convention the scene follows; a scene two tracks claim is refused in
    one line (a scene belongs to one track), one no track claims goes to the fallback track."""
    marks = scene_marks(scene)
    claims = [t for t in iter_tracks() if t.claims_scene(marks)]
    if len(claims) > 1:
        raise UserError(f"MJCF {marks.path} follows the conventions of the {' and '.join(t.name for t in claims)} "
                        f"tracks (lm* sites: camera landmarks, lm* geoms: posts, lw* geoms: walls): a scene "
                        f"belongs to one track; rename one kind (e.g. the posts' geoms to post*, the walls to wall*)")
    if claims:
        return claims[0]
    return next(t for t in iter_tracks() if t.fallback)


def track_for_method(method: str) -> Track | None:
    """The track that owns ``method``, or None when the method serves any scene's track."""
    return next((t for t in iter_tracks() if t.claims_method(method)), None)


def track_for_run(scene: str | Path, method: str) -> Track:
    """The track of a run: the method's own track when it has one, else the scene's."""
    return track_for_method(method) or track_for_scene(scene)


def scene_track(scene: str | Path) -> str:
    """The name of the scene's track (``track_for_scene``)."""
    return track_for_scene(scene).name
