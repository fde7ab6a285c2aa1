"""Gymnasium environment: one episode is one pass along a rendered trajectory; each step is
one frame's association problem.

Observation (``Dict``, padded to fixed maxima so ``gymnasium.make_vec`` works in both modes):

* ``features`` (M, 2) pixels, ``feature_cov`` (M, 2, 2) their noise R, ``feature_mask`` (M,);
* ``predictions`` (N, 2), ``prediction_cov`` (N, 2, 2) the marginal blocks of P,
  ``landmark_mask`` (N,). The full joint covariance with cross terms is in ``info["problem"]``.

Action: ``MultiDiscrete`` of N entries in [-1, M-1]: the feature paired with each candidate,
-1 for none; padded candidates must be -1. An invalid action (wrong shape, a padded slot
used, an index beyond the frame's features, a feature used twice) is never scored silently:
with ``invalid_action="penalize"`` (default) the step's reward is ``-n`` (as if every
candidate were paired wrongly), nothing is counted as found, and ``info["invalid_action"]``
says what was wrong; with ``invalid_action="raise"`` the step raises ``ValueError``.

Reward: TP − FP of the step (a wrong pairing costs as much as a right one earns).

``info``: ``problem`` (the ``Problem``, so classical associators can act), ``truth`` (the true
association), ``frame``, and after a step the step's metrics (``tp``, ``fp``, ``fn``, ...).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..association.compatibility import marginal_blocks
from ..association.problem import NO_MATCH, Problem, validate_association
from ..belief.camera_belief import make_problem
from ..errors import UserError
from ..harness.config import DEFAULTS, merge, run_spec
from ..harness.suite import shipped_difficulties
from ..scoring.metrics import score_frame, unscored_frame
from ..sim.sequence import Sequence, load_sequence


class AssociationEnv(gym.Env):
    """Data association on a MuJoCo scene as a Gymnasium environment (see module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, scene: str = "room", trajectory: str | None = None, frames: int = 20,
                 difficulty: str | dict = "medium", resolution: tuple[int, int] = (640, 480),
                 render_mode: str | None = None, config: dict | None = None,
                 invalid_action: str = "penalize") -> None:
        if render_mode not in (None, "rgb_array"):
            raise UserError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if invalid_action not in ("penalize", "raise"):
            raise UserError(f"invalid_action must be 'penalize' or 'raise', got {invalid_action!r}")
        self.invalid_action = invalid_action
        levels = shipped_difficulties()
        if isinstance(difficulty, str) and difficulty not in levels:
            raise UserError(f"unknown difficulty {difficulty!r}: choose one of {', '.join(levels)} or pass a mapping")
        override = levels[difficulty] if isinstance(difficulty, str) else {"belief": dict(difficulty)}
        cfg = merge(merge(DEFAULTS, override, "difficulty"), config or {}, "config")
        self._cfg = merge(cfg, {"scene": scene, "trajectory": trajectory, "frames": frames,
                                "resolution": list(resolution)}, "env arguments")
        spec = run_spec(self._cfg)
        from ..sim.scene import load_scene

        n_max = len(load_scene(spec.sequence.scene).landmarks)
        m_max = spec.sequence.detector.max_features + spec.belief.clutter
        self.max_landmarks, self.max_features = n_max, m_max
        self.render_mode = render_mode
        big = np.float64(1e9)
        self.observation_space = spaces.Dict({
            "features": spaces.Box(-big, big, (m_max, 2), np.float64),
            "feature_cov": spaces.Box(-big, big, (m_max, 2, 2), np.float64),
            "feature_mask": spaces.MultiBinary(m_max),
            "predictions": spaces.Box(-big, big, (n_max, 2), np.float64),
            "prediction_cov": spaces.Box(-big, big, (n_max, 2, 2), np.float64),
            "landmark_mask": spaces.MultiBinary(n_max),
        })
        self.action_space = spaces.MultiDiscrete(np.full(n_max, m_max + 1), start=np.full(n_max, NO_MATCH))
        self._seq: Sequence | None = None
        self._seed = 0
        self._frame = 0
        self._problem = self._truth = None
        self._last: tuple | None = None   # (frame, problem, association) of the last step
        self._renderer = None

    # -- episode -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._seed = int(seed) if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        spec = run_spec(merge(self._cfg, {"seed": self._seed}, "seed"))
        self._belief = spec.belief
        self._seq = load_sequence(spec.sequence)
        self._spec = spec
        self._frame = 0
        self._last = None
        self._load_frame()
        return self._observation(), self._info()

    def step(self, action):
        if self._problem is None:
            raise RuntimeError("call reset() before step()")
        try:
            association = self._check_action(action)
        except ValueError as exc:
            if self.invalid_action == "raise":
                raise
            metrics = unscored_frame(self._problem, self._truth)
            reward, info = -float(self._problem.n), {"invalid_action": str(exc)}
            association = np.full(self._problem.n, NO_MATCH)
        else:
            metrics = score_frame(self._problem, self._truth, association)
            reward, info = float(metrics["tp"] - metrics["fp"]), {}
        self._last = (self._frame, self._problem, association)
        info.update(step_metrics=metrics, scored_frame=self._frame)
        self._frame += 1
        terminated = self._frame >= len(self._seq)
        if not terminated:
            self._load_frame()
        return self._observation(), reward, terminated, False, {**self._info(), **info}

    def _load_frame(self) -> None:
        self._problem, self._truth = make_problem(self._seq, self._frame, self._belief, self._seed)

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
        p, M, N = self._problem, self.max_features, self.max_landmarks
        obs = {
            "features": np.zeros((M, 2)), "feature_cov": np.zeros((M, 2, 2)),
            "feature_mask": np.zeros(M, np.int8), "predictions": np.zeros((N, 2)),
            "prediction_cov": np.zeros((N, 2, 2)), "landmark_mask": np.zeros(N, np.int8),
        }
        obs["features"][: p.m] = p.z
        obs["feature_cov"][: p.m] = p.R
        obs["feature_mask"][: p.m] = 1
        obs["predictions"][: p.n] = p.zhat
        obs["prediction_cov"][: p.n] = marginal_blocks(p)
        obs["landmark_mask"][: p.n] = 1
        return obs

    def _info(self) -> dict[str, Any]:
        if self._frame >= len(self._seq):
            return {"frame": self._frame}
        return {"problem": self._problem, "truth": self._truth.association, "frame": self._frame}

    # -- pictures ------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """The frame of the last step with that step's association drawn (lab-8 colours);
        right after ``reset``, the first frame with its predictions and no association."""
        if self.render_mode != "rgb_array" or self._problem is None:
            return None
        from ..sim.render import FrameRenderer
        from ..sim.scene import load_scene
        from ..viz.overlay import draw_association

        k, problem, association = self._last or (self._frame, self._problem, np.full(self._problem.n, NO_MATCH))
        if self._renderer is None:
            s = self._spec.sequence
            self._renderer = FrameRenderer(load_scene(s.scene), s.width, s.height, s.msaa)
        rgb = self._renderer.render(self._seq.rotations[k], self._seq.positions[k])["rgb"]
        return draw_association(rgb, problem, association)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def classical_action(info: dict, size: int, method: str = "jcbb", **params) -> np.ndarray:
    """The action a classical associator takes for ``info["problem"]``, padded to ``size`` slots."""
    from ..associators.registry import make_associator

    problem: Problem = info["problem"]
    out = np.full(size, NO_MATCH, dtype=np.int64)
    out[: problem.n] = make_associator(method, **params).associate(problem)
    return out
