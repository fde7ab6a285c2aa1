"""Closed-loop Gymnasium environments: ``assocbench/RoomLoop-v0`` and one id per shipped scene of
every track with a closed loop (``ClosedLoop``) that offers envs.

The belief of each frame is the track's estimator's posterior (an EKF, an iSAM2 factor graph:
the track's ``ClosedLoop``) after the agent's own earlier actions
(``harness.loop.ClosedLoop``): ``reset`` starts the filter at frame 0 and observes frame 0's
problem; ``step(action)`` scores the action, updates the filter with it (in ``slam`` mode the
features it left unpaired become landmarks), predicts to the next frame with odometry and
observes that frame's problem, predicted from the updated filter. A wrong pairing therefore
corrupts the estimate, and the next observations with it.

Observation, action, reward (TP − FP), ``info`` and the end of an episode are the open env's
(``env.py``), with two differences:

* candidate slots N: the scene's map (``Track.env_slots``) in ``localisation``; in ``slam`` the
  map grows from the features up to ``estimator.max_landmarks`` entries (texture corners
  included), so N = max(scene landmarks, ``estimator.max_landmarks``);
* an invalid action (with ``invalid_action="penalize"``) is a failed frame, as in ``--loop``
  runs: the filter is not updated, it only predicts through the frame.

After each step ``info`` also holds the filter's state at ``scored_frame`` after the update
(the per-frame columns of ``assocbench run --loop``), all scalars: ``pos_err`` (m),
``rot_err_deg``, ``nees`` (pose NEES: 6 dof in space, 3 in the plane; NaN while the pose covariance is zero, as at
slam's first frame) and ``map_size`` (confirmed landmarks).
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
    """The run-config override of a closed-loop env: ``config``, then ``estimator`` (a mapping of
    ``estimator.*`` settings), then ``mode``; ``loop`` is always true. Values are checked later
    by ``run_spec``; this refuses what it cannot merge, in one line."""
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
    """Data association in the closed loop as a Gymnasium environment (see module docstring).

    Arguments are the open env's plus ``mode`` (``localisation`` or ``slam``; None keeps
    ``estimator.mode``, default localisation) and ``estimator`` (``estimator.*`` overrides such as
    ``{"odometry_sigma_rotation": 0.5}``); ``config`` may hold an ``estimator`` section too."""

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
        """Frame ``k``'s problem from the filter: a new filter at frame 0 (reset), else the
        prediction from the last frame's posterior by odometry."""
        if self._frame == 0:
            from ..harness.loop import ClosedLoop

            self._loop = ClosedLoop(self._seq, self._spec)
        self._take(*self._loop.begin(self._frame))

    def _picture_estimator(self):
        """A copy of the filter as it is now (after this frame's update): the next frame's
        prediction moves the filter on before ``render`` draws this one. The live filter where it
        cannot be copied (a back end's native objects)."""
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
