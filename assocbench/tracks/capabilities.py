"""What a track may offer beyond its core (``tracks.base``): protocols the harness discovers with
``has(track, Capability)``. None is assumed; a command needing one the track lacks says so in one
line (``lacks``).

=====================  ========================================================================
``OwnFrames``          frames that are not association problems: the track's own frame loop, its
                       summary and its methods (the dense track: ICP on depth frames)
``ClosedLoop``         an estimator updated with the method's own pairings (``--loop``)
``Pictures``           ``assocbench frame`` and ``render``: one frame with its truth, a run's frames
``GymEnvs``            Gymnasium envs (ids and the padded sizes of their spaces)
``WarmUp``             compiled kernels loaded once before any frame is timed
``TopView``            the leaderboard's top view of a closed-loop scene
``OwnLeaderboard``     leaderboard files of its own instead of the shared CSV, Markdown and plots
``RunFiles``           files a run writes beside its CSVs (the dense track's map)
``SceneConvention``    inferring the track of an MJCF file from what it names (when no ``track``)
``OwnMethods``         methods only this track runs (they then imply it)
``Trajectories``       named paths for ``assocbench list``
``Requirements``       an optional package the track needs (listed as unavailable without it)
``RunScores``          summary columns of its own, computed from a run's per-frame records
=====================  ========================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..errors import UserError


class MethodCalls(Protocol):
    """The plugin boundary a track's own frame loop calls its method through (the harness implements
    it): each call announced to the supervisor, timed, and what it raises made the frame's
    ``error``. ``faults``: frames known failed -> ``(error, runtime_s)``; key -1: the method could
    not be built."""

    faults: dict

    def build(self, make: Callable[[], Any]) -> tuple[Any | None, str]:
        """``(make(), "")``, or ``(None, error)`` when building the method failed."""

    def call(self, k: int, fn: Callable[[], Any]) -> tuple[Any | None, float, str]:
        """``(fn(), seconds, "")`` for frame ``k``, or ``(None, seconds, error)``."""


@runtime_checkable
class OwnFrames(Protocol):
    """Frames that are not association problems: the track runs its own frame loop."""

    def records(self, source: Any, run: Any, calls: MethodCalls, first: int = 0,
                artifacts: Path | None = None) -> Iterator[dict]:
        """Per-frame records from ``first`` on, the method called through ``calls``; ``artifacts``:
        a folder for end-of-run files, or None."""

    def summarize(self, frames: Any) -> dict:
        """The summary row of a run's per-frame records (a pandas DataFrame)."""

    def check_method(self, method: str, params: dict) -> None:
        """Refuse, in one line, a method this track cannot run or bad parameters."""

    def describe(self, run: Any) -> tuple[dict, str]:
        """Columns that say how the run was made and the same in words (``tracking: model``)."""


@runtime_checkable
class ClosedLoop(Protocol):
    """A closed loop: the belief of frame k is the estimator's posterior after frames < k were
    updated with the method's pairings (``harness.loop``)."""

    estimator_words: str   # what the leaderboard says updates the loop ("camera EKF-SLAM")

    def estimator(self, source: Any, run: Any) -> Any:
        """The estimator at frame 0."""

    def loop_sensor(self, source: Any, run: Any) -> Any:
        """What the loop reads each frame: measurements, odometry, pose columns."""


@dataclass(frozen=True)
class RunFrame:
    """One recorded frame rebuilt for its picture: the ``problem`` and ``truth``, the recorded
    ``association`` (all −1 on a failed frame) and ``error``, the run's ``record`` of it, and in the
    closed loop the ``estimator`` after its update (valid until the next frame is replayed; None
    open loop)."""

    k: int
    problem: Problem
    truth: FrameTruth
    association: np.ndarray
    error: str
    record: dict
    estimator: Any = None


@runtime_checkable
class Pictures(Protocol):
    """``assocbench frame`` and ``assocbench render``."""

    def frame_picture(self, run: Any, index: int) -> tuple[np.ndarray, str]:
        """Frame ``index`` with its truth drawn, RGB (H, W, 3) uint8, and one line of what it shows."""

    def run_pictures(self, run: Any, source: Any, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
        """One RGB picture per recorded frame, all of one size, showing what the method decided."""


@dataclass(frozen=True)
class GymEnv:
    """One Gymnasium env: its ``id`` (``assocbench/<Scene>-v0``, ``<Scene>Loop-v0`` closed loop),
    its ``scene`` and whether it is the closed ``loop``."""

    id: str
    scene: str
    loop: bool = False


class EnvSlots(NamedTuple):
    """The padded sizes of a track's env: ``landmarks`` (N) and ``features`` (M) slots no frame
    exceeds whatever the seed, and ``dim`` (d) of a measurement."""

    landmarks: int
    features: int
    dim: int = 2


@runtime_checkable
class GymEnvs(Protocol):
    """Gymnasium envs (``assocbench.gymenv``); a track whose frames are ``Problem``s."""

    def gym_envs(self) -> tuple[GymEnv, ...]:
        """Its envs (``gym_envs_of`` makes the usual ids from its scenes)."""

    def env_slots(self, run: Any) -> EnvSlots:
        """The padded sizes of its env for the run ``run``."""


def gym_envs_of(scenes: Iterable[str], modes: Iterable[str]) -> tuple[GymEnv, ...]:
    """Per scene and mode the id ``assocbench/<Scene>-v0`` or ``<Scene>Loop-v0``, the scene in
    CamelCase (``post_grid`` -> ``PostGrid``)."""
    suffix = {"open": "", "loop": "Loop"}
    modes = tuple(modes)
    return tuple(GymEnv(f"assocbench/{''.join(p.capitalize() for p in scene.split('_'))}{suffix[mode]}-v0",
                        scene, mode == "loop") for scene in scenes for mode in modes)


@runtime_checkable
class WarmUp(Protocol):
    """Kernels loaded (or compiled, announced on stderr) once in the process workers fork from, so
    no frame's time includes a compile."""

    def warm_up(self) -> None: ...


@runtime_checkable
class TopView(Protocol):
    """The leaderboard's top view of a closed-loop scene."""

    def map_figure(self, frames: Any, scene: str, title: str) -> Any:
        """A figure of one seed's closed-loop ``frames`` on ``scene``: every method's run over the
        true map."""


@runtime_checkable
class OwnLeaderboard(Protocol):
    """Leaderboard files of its own (all or none) instead of the shared ones."""

    def leaderboard_table(self, summaries: Any) -> Any:
        """One row per scenario × method (what ``check`` compares)."""

    def write_leaderboard(self, summaries: Any, frames: Any, out: Path) -> dict:
        """Write its files into ``out``: ``{"md": path, ...}``."""


@runtime_checkable
class RunFiles(Protocol):
    """Files one run writes beside its CSVs."""

    def run_files(self, frames: Any, artifacts: Path, out: Path, title: str) -> dict:
        """``{path: write(path)}`` from the run's frames and the end-of-run files in ``artifacts``."""


@dataclass(frozen=True)
class SceneMarks:
    """What an MJCF names, read without compiling it: ``lm*`` sites, ``lm*`` and ``lw*`` geoms, and
    its ``path``."""

    path: Path
    landmark_sites: int
    landmark_geoms: int
    wall_geoms: int


@runtime_checkable
class SceneConvention(Protocol):
    """Which MJCF files are this track's when a run names no ``track`` (the fallback)."""

    def claims_scene(self, marks: SceneMarks) -> bool: ...


@runtime_checkable
class OwnMethods(Protocol):
    """Methods only this track runs: naming one implies the track."""

    def claims_method(self, method: str) -> bool: ...


@runtime_checkable
class Trajectories(Protocol):
    """Named paths for ``assocbench list``."""

    def trajectories(self) -> list[tuple[str, str]]: ...


@runtime_checkable
class Requirements(Protocol):
    """An optional package a track needs."""

    def unavailable(self) -> str | None:
        """Why the track cannot run here (``gtsam is not installed: pip install ...``), or None."""


@runtime_checkable
class RunScores(Protocol):
    """Summary columns of its own computed from a whole run's records (a recorded track's pairwise
    "same landmark" precision); listed in its ``Columns.summary``."""

    def run_scores(self, frames: Any) -> dict:
        """``{column: value}`` from a run's per-frame records (a pandas DataFrame)."""


def has(track: Any, capability: type) -> bool:
    """Whether ``track`` offers ``capability`` (one of this module's protocols)."""
    return isinstance(track, capability)


def lacks(track: Any, what: str, instead: str = "") -> UserError:
    """The one-line error for a command that needs a capability the run's track does not have."""
    return UserError(f"the {track.name} track has no {what}" + (f": {instead}" if instead else ""))
