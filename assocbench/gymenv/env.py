"""Gymnasium environment: an episode is one pass along a track's trajectory, a step one frame's
association problem; one class serves every track offering envs (``GymEnvs``).

Observation (``Dict``, padded to fixed maxima for ``gymnasium.make_vec``): ``features`` (M, d) in
the track's units, ``feature_cov`` (M, d, d), ``feature_mask`` (M,); ``predictions`` (N, d),
``prediction_cov`` (N, d, d) the marginal blocks of P, ``landmark_mask`` (N,); the joint covariance
and angular dims in ``info["problem"]``. A terminating step observes nothing.

Action: ``MultiDiscrete`` of N entries in [-1, M-1], each candidate's feature (padded slots -1;
``info["action_mask"]``, ``actions.py``). An invalid action is never scored silently:
``invalid_action="penalize"`` (default) rewards ``-n``, counts nothing found, sets
``jointly_compatible`` False and says why in ``info["invalid_action"]``; ``"raise"`` raises
``ValueError``. Reward: TP − FP.

``info`` (fixed-size, vector envs stack it): ``problem`` (absent once over), ``truth`` (N,),
``action_mask``, ``frame``, after a step ``scored_frame`` and ``step_metrics``. After
``terminated``, ``step()`` raises ``ResetNeeded``. ``render_mode="rgb_array"`` draws as
``assocbench render`` does; a process forked after MuJoCo rendered cannot render (GL does not
survive ``fork``), so ``reset`` there raises a one-line ``UserError`` instead of hanging.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from ..association.compatibility import marginal_blocks
from ..association.problem import NO_MATCH, Problem, validate_association
from ..errors import UserError
from ..harness.config import RunSpec, merge, run_spec
from ..harness.runner import Problems, checked_truth, load_source
from ..scoring.metrics import score_frame
from ..tracks.capabilities import EnvSlots, Pictures, RunFrame, has
from .actions import action_mask
from .arguments import env_config, env_track

_FORKED_AFTER_EGL = False   # this process was forked from one that had already rendered with EGL


def invalid_action_metrics(problem: Problem, truth) -> dict:
    """``step_metrics`` of an invalid action: the empty answer's counts with ``jointly_compatible``
    False (not NaN: Gymnasium's checker compares infos with ``==``)."""
    return score_frame(problem, truth, np.full(problem.n, NO_MATCH, dtype=np.int64)) | {"jointly_compatible": False}


def _note_fork() -> None:
    """In every forked child: remember whether the parent made an EGL context, since the child's
    first render would wait forever on the driver's lost threads."""
    global _FORKED_AFTER_EGL
    egl = sys.modules.get("mujoco.egl")
    _FORKED_AFTER_EGL = _FORKED_AFTER_EGL or getattr(egl, "EGL_DISPLAY", None) is not None


os.register_at_fork(after_in_child=_note_fork)


def _check_can_render() -> None:
    if _FORKED_AFTER_EGL:
        raise UserError("this process was forked from one that had already rendered with EGL, and the GL driver "
                        "cannot render after fork (it would hang): create async vector envs before rendering, or "
                        "pass vector_kwargs={'context': 'forkserver'} (or 'spawn') to gymnasium.make_vec")


class AssociationEnv(gym.Env):
    """Data association on a MuJoCo scene as a Gymnasium environment (see module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}   # per instance: none on a track with no pictures

    def __init__(self, scene: str = "room", trajectory: str | None = None, frames: int = 20,
                 difficulty: str | dict | None = None, resolution: tuple[int, int] = (640, 480),
                 render_mode: str | None = None, config: dict | None = None,
                 invalid_action: str = "penalize", track: str | None = None) -> None:
        if render_mode not in (None, "rgb_array"):
            raise UserError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if invalid_action not in ("penalize", "raise"):
            raise UserError(f"invalid_action must be 'penalize' or 'raise', got {invalid_action!r}")
        self.invalid_action = invalid_action
        self._cfg, spec = env_config(scene, trajectory, frames, difficulty, resolution, config, track)
        self._track = env_track(spec)
        self._gl = getattr(self._track, "renders_frames", False)   # its pictures are MuJoCo GL renders
        pictures = has(self._track, Pictures)
        if render_mode is not None and not pictures:
            raise UserError(f"render_mode {render_mode!r} draws the track's pictures, which the {self._track.name} "
                            f"track (scene {spec.source.name!r}) has not: pass render_mode=None")
        self.metadata = {**self.metadata, "render_modes": ["rgb_array"] if pictures else []}
        n_max, m_max, d = self._slots(spec)
        self.max_landmarks, self.max_features, self.dim = n_max, m_max, d
        self.render_mode = render_mode
        big = np.float64(1e9)
        self.observation_space = spaces.Dict({
            "features": spaces.Box(-big, big, (m_max, d), np.float64),
            "feature_cov": spaces.Box(-big, big, (m_max, d, d), np.float64),
            "feature_mask": spaces.MultiBinary(m_max),
            "predictions": spaces.Box(-big, big, (n_max, d), np.float64),
            "prediction_cov": spaces.Box(-big, big, (n_max, d, d), np.float64),
            "landmark_mask": spaces.MultiBinary(n_max),
        })
        self.action_space = spaces.MultiDiscrete(np.full(n_max, m_max + 1), start=np.full(n_max, NO_MATCH))
        self._seq = None
        self._problems = None
        self._seed = 0
        self._frame = 0
        self._problem = self._truth = None
        self._last: RunFrame | None = None   # the last step's frame, as its picture draws it
        self._pictures: Iterator[np.ndarray] | None = None   # the episode's top views (``_top_view``)
        self._feed = _Feed()

    # -- episode -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start the episode of ``seed`` (from the env's generator when None); reset options are
        refused, not ignored."""
        if options:
            raise UserError(f"AssociationEnv.reset takes no options, got {sorted(options)}; "
                            "pass settings to the constructor (gymnasium.make kwargs)")
        if self._gl:   # a track of no GL images never renders: a forked worker may run it
            _check_can_render()
        super().reset(seed=seed)
        self._seq = self._problem = self._truth = None   # a reset that fails leaves no episode to step
        seed = int(seed) if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        spec = run_spec(merge(self._cfg, {"seed": seed}, "seed"))
        self._seq = spec.source
        load_source(self._seq, None)
        self._seed, self._spec, self._belief = seed, spec, spec.belief
        self.close()   # the last episode's pictures
        self._frame = 0
        self._last = self._pictures = None
        self._load_frame()
        return self._observation(), self._info()

    def step(self, action):
        """Score ``action`` on the current frame and move to the next (see module docstring)."""
        if self._seq is None:
            raise ResetNeeded("call reset() before step()")
        if self._over:
            raise ResetNeeded(f"the episode is over (all {len(self._seq)} frames were scored and the last step "
                              "returned terminated=True): call reset() to start a new one")
        try:
            association = self._check_action(action)
        except ValueError as exc:
            if self.invalid_action == "raise":
                raise
            metrics = invalid_action_metrics(self._problem, self._truth)
            reward, info = -float(self._problem.n), {"invalid_action": str(exc)}
            info.update(self._apply(None, str(exc)))
            association = np.full(self._problem.n, NO_MATCH)
        else:
            metrics = score_frame(self._problem, self._truth, association)
            reward, info = float(metrics["tp"] - metrics["fp"]), self._apply(association, "")
        self._last = self._run_frame(association, metrics | info, info.get("invalid_action", ""))
        info.update(step_metrics=metrics, scored_frame=self._frame)
        self._frame += 1
        if not self._over:
            self._load_frame()
        return self._observation(), reward, self._over, False, {**self._info(), **info}

    @property
    def _over(self) -> bool:
        return self._frame >= len(self._seq)

    def _slots(self, spec: RunSpec) -> EnvSlots:
        """N, M and d: the track's bounds (``Track.env_slots``)."""
        return self._track.env_slots(spec)

    def _load_frame(self) -> None:
        """The open loop's frame: its problem made when the episode reaches it (the track's
        ``problem``, as ``assocbench run`` makes it)."""
        if self._frame == 0:
            self._problems = Problems(self._track, self._seq, self._spec)
        self._take(*self._problems[self._frame])

    def _take(self, problem: Problem, truth) -> None:
        """Make ``problem`` the current frame, refusing one larger than the padded spaces in one
        line (a track bug, not a broadcasting error)."""
        problem.validate()          # the whole P, as the harness checks it, before the agent sees it
        checked_truth(self._track.name, self._frame, problem, truth)   # and the truth it is scored against
        if problem.n > self.max_landmarks or problem.m > self.max_features or problem.d != self.dim:
            raise RuntimeError(f"frame {self._frame} has {problem.n} candidates and {problem.m} features of dimension "
                               f"{problem.d}, beyond the env's {self.max_landmarks} x {self.max_features} slots of "
                               f"dimension {self.dim}: the {self._track.name} track's env_slots is not a bound")
        self._problem, self._truth = problem, truth

    def _apply(self, association: np.ndarray | None, error: str) -> dict[str, Any]:
        """Act on the frame's answer (None: refused with ``error``) before the next frame loads;
        returns extra ``info``."""
        return {}

    def _check_action(self, action) -> np.ndarray:
        a = np.asarray(action)
        if a.shape != (self.max_landmarks,):
            raise ValueError(f"action has shape {a.shape}, expected ({self.max_landmarks},): one entry per candidate slot")
        n = self._problem.n
        if np.any(a[n:] != NO_MATCH):
            raise ValueError(f"action pairs padded candidate slots {np.flatnonzero(a[n:] != NO_MATCH)[:5] + n}; "
                             f"only the first {n} are real, the rest must be -1")
        return validate_association(a[:n], self._problem)

    # -- observation ---------------------------------------------------------------------
    def _observation(self) -> dict[str, np.ndarray]:
        """The current frame padded to the space's sizes; all zeros (empty masks) once over."""
        M, N, d = self.max_features, self.max_landmarks, self.dim
        obs = {
            "features": np.zeros((M, d)), "feature_cov": np.zeros((M, d, d)),
            "feature_mask": np.zeros(M, np.int8), "predictions": np.zeros((N, d)),
            "prediction_cov": np.zeros((N, d, d)), "landmark_mask": np.zeros(N, np.int8),
        }
        if self._over:
            return obs
        p = self._problem
        obs["features"][: p.m] = p.z
        obs["feature_cov"][: p.m] = p.R
        obs["feature_mask"][: p.m] = 1
        obs["predictions"][: p.n] = p.zhat
        obs["prediction_cov"][: p.n] = marginal_blocks(p)
        obs["landmark_mask"][: p.n] = 1
        return obs

    def _info(self) -> dict[str, Any]:
        """Fixed-size entries only (a vector env stacks them; see module docstring)."""
        truth = np.full(self.max_landmarks, NO_MATCH, dtype=np.int64)
        if self._over:
            mask = action_mask(0, 0, self.max_landmarks, self.max_features)
            return {"truth": truth, "action_mask": mask, "frame": self._frame}
        p = self._problem
        truth[: p.n] = self._truth.association
        mask = action_mask(p.n, p.m, self.max_landmarks, self.max_features)
        return {"problem": p, "truth": truth, "action_mask": mask, "frame": self._frame}

    # -- pictures ------------------------------------------------------------------------
    def _run_frame(self, association: np.ndarray, record: dict, error: str = "") -> RunFrame | None:
        """The current frame as its picture draws it (None: nothing drawn)."""
        if self.render_mode != "rgb_array":
            return None
        return RunFrame(self._frame, self._problem, self._truth, association, error, record, self._picture_estimator())

    def _picture_estimator(self):
        """The estimator a picture draws (none in the open loop), as it is now."""
        return None

    def render(self) -> np.ndarray | None:
        """The last step's frame with its association drawn as ``assocbench render`` draws a run
        (the agent in the method's place); after ``reset``, the first frame with no association.
        One drawing per episode, fed frame by frame."""
        if self.render_mode != "rgb_array" or self._problem is None:
            return None
        empty = np.full(self._problem.n, NO_MATCH)
        self._feed.item = self._last or self._run_frame(empty, score_frame(self._problem, self._truth, empty))
        if self._pictures is None:
            if self._gl:
                _check_can_render()
            self._pictures = self._track.run_pictures(self._spec.with_method("agent", {}), self._seq, self._feed)
        return next(self._pictures)

    def close(self) -> None:
        if self._pictures is not None:
            self._pictures.close()   # the drawing's own cleanup (a renderer's GL context) runs now
            self._pictures = None


class _Feed:
    """An endless iterator of the next frame to draw, so one ``run_pictures`` drawing serves an
    episode."""

    item: RunFrame | None = None

    def __iter__(self):
        return self

    def __next__(self) -> RunFrame:
        return self.item


def classical_action(info: dict, size: int, method: str = "jcbb", **params) -> np.ndarray:
    """The action a classical associator takes for ``info["problem"]``, padded to ``size`` slots."""
    from ..associators.registry import make_associator

    problem: Problem = info["problem"]
    out = np.full(size, NO_MATCH, dtype=np.int64)
    out[: problem.n] = make_associator(method, **params).associate(problem)
    return out
