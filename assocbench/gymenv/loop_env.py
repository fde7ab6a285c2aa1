"""Closed-loop Gymnasium environments: ``assocbench/<Scene>Loop-v0`` per shipped scene of each track
with a closed loop and envs. Each frame's belief is the track's estimator after the agent's own
earlier actions (``harness.loop.ClosedLoop``): ``step(action)`` scores it, updates the filter (slam:
unpaired features become landmarks), predicts by odometry and observes the next problem, so a wrong
pairing corrupts the next observations.

As the open env (``env.py``), except: N is the scene's map in ``localisation``, max(scene landmarks,
``estimator.max_landmarks``) in ``slam``; an invalid action (``"penalize"``) is a failed frame (no
update). ``info`` also holds the filter's state after the update: ``pos_err`` (m), ``rot_err_deg``,
``nees`` (NaN while the covariance is zero) and ``map_size``.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import UserError
from ..estimators.config import MODES
from ..harness.config import RunSpec
from ..tracks.capabilities import EnvSlots
from .env import AssociationEnv

if TYPE_CHECKING:   # imported when an episode starts: `import assocbench` stays free of the harness
    from ..harness.loop import ClosedLoop

LOOP_INFO = ("pos_err", "rot_err_deg", "nees", "map_size")


def loop_config(config: Any, mode: Any, estimator: Any) -> dict:
    """The override of a closed-loop env: ``config``, then ``estimator`` settings, then ``mode``;
    ``loop`` true. Values are checked later (``run_spec``); this refuses what it cannot merge."""
    if config is not None and not isinstance(config, Mapping):
        raise UserError(f"config must be a mapping of run-config overrides, got {config!r}")
    if estimator is not None and not isinstance(estimator, Mapping):
        raise UserError(f"estimator must be a mapping of estimator settings (such as {{'mode': 'slam'}}), "
                        f"got {estimator!r}")
    if mode is not None and mode not in MODES:
        raise UserError(f"mode must be one of {', '.join(MODES)} (or None for estimator.mode), got {mode!r}")
    cfg = dict(config or {})
    if cfg.get("loop", True) is not True:
        raise UserError(f"the closed-loop envs always run the loop: drop loop={cfg['loop']!r} from config "
                        "(or use the open env, assocbench/Room-v0)")
    section = cfg.get("estimator") or {}
    if not isinstance(section, Mapping):
        raise UserError(f"config['estimator'] must be a mapping of estimator settings, got {section!r}")
    section = {**section, **(estimator or {}), **({"mode": mode} if mode is not None else {})}
    return {**cfg, "loop": True, **({"estimator": section} if section else {})}


class LoopAssociationEnv(AssociationEnv):
    """Data association in the closed loop as a Gymnasium environment: the open env's arguments plus
    ``mode`` (None: ``estimator.mode``) and ``estimator`` (``estimator.*`` overrides); ``config``
    may hold an ``estimator`` section too."""

    def __init__(self, scene: str = "room", trajectory: str | None = None, frames: int = 20,
                 difficulty: str | dict | None = None, resolution: tuple[int, int] = (640, 480),
                 render_mode: str | None = None, config: dict | None = None,
                 invalid_action: str = "penalize", mode: str | None = None,
                 estimator: dict | None = None, track: str | None = None) -> None:
        self._loop: ClosedLoop | None = None
        super().__init__(scene, trajectory, frames, difficulty, resolution, render_mode,
                         loop_config(config, mode, estimator), invalid_action, track)

    @property
    def filter(self):
        """The estimator of the current episode (None before the first reset)."""
        return self._loop.filter if self._loop is not None else None

    def _slots(self, spec: RunSpec) -> EnvSlots:
        """N: the scene's map; in slam, at least ``estimator.max_landmarks`` (the map grows)."""
        slots = super()._slots(spec)
        if spec.estimator.mode == "slam":
            return slots._replace(landmarks=max(slots.landmarks, spec.estimator.max_landmarks))
        return slots

    def _load_frame(self) -> None:
        """Frame ``k``'s problem from the filter: a new filter at reset, else predicted from the
        last posterior."""
        if self._frame == 0:
            from ..harness.loop import ClosedLoop

            self._loop = ClosedLoop(self._seq, self._spec)
        self._take(*self._loop.begin(self._frame))

    def _picture_estimator(self):
        """A copy of the filter after this frame's update (the next prediction moves it before
        ``render``); the live one where it cannot be copied."""
        try:
            return copy.deepcopy(self._loop.filter)
        except Exception:  # noqa: BLE001 - any back end's copy failure: draw the live one
            return self._loop.filter

    def _run_frame(self, association: np.ndarray, record: dict, error: str = ""):
        """The open env's, with the filter's pose error in the record (the picture's caption)."""
        rf = super()._run_frame(association, record, error)
        if rf is None or rf.estimator is None:
            return rf
        return replace(rf, record={**self._loop.sensor.state_columns(rf.estimator, self._frame), **rf.record})

    def _apply(self, association: np.ndarray | None, error: str) -> dict[str, Any]:
        """Update the filter with the action (None: a failed frame, no update) and report its state."""
        record = self._loop.finish(association, error=error)
        info = {key: record[key] for key in LOOP_INFO}
        if record["error"] and association is not None:   # the update itself failed (not positive definite)
            info["filter_error"] = record["error"]
        return info
