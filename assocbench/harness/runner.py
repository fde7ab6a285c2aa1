"""One run: a cached sequence, a belief per frame, one associator, scored frame by frame. The frame
loop (``frame_records``) runs in a worker (``sandbox.execute``), so the parent can enforce a time
limit and survive a method that dies. The plugin boundary is ``call_method``: anything a method
raises, ``SystemExit`` included, fails that frame, and every call gets its own copy of the problem,
so a method editing it changes neither the scoring nor what later methods see.
"""

from __future__ import annotations

import copy
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..association.problem import DESCRIPTOR_FIELDS, NO_MATCH, Problem, validate_association
from ..association.truth import FrameTruth
from ..associators.registry import make_associator
from ..errors import UserError
from ..scoring.aggregate import summarize
from ..scoring.metrics import score_frame, true_mass, unscored_frame
from ..tracks.base import loop_words
from ..tracks.capabilities import OwnFrames, RunScores, has
from .imports import for_every_method

WARM_UP = -1          # the call index of building the associator and its warm-up call
METHOD, TRACK = "method", "track"   # whose code a call runs: the method's, or the track's (a frame's problem)
WARM_UP_FACTOR = 10   # warm-up may compile (numba, a plugin's JIT): it gets 10x the per-call limit
_ARRAYS = ("z", "R", "zhat", "P", "landmark_ids")


def tiny_problem() -> Problem:
    """Two landmarks, two features: enough to load every compiled kernel a method or the scoring uses."""
    return Problem(np.array([[0.0, 0.0], [5.0, 0.0]]), np.repeat(np.eye(2)[None], 2, axis=0),
                   np.array([[0.2, 0.1], [5.1, 0.2]]), np.eye(4), volume=100.0)


def warm_scoring() -> None:
    """Load the scoring's compiled kernels (the joint test and surprisal of ``score_frame``)."""
    tiny = tiny_problem()
    score_frame(tiny, FrameTruth(np.array([0, -1]), np.array([0, -1]), np.array([True, False])), np.array([0, 1]))


def warm_up(associator) -> None:
    """Run ``associator`` once on a tiny problem so loading kernels is not timed; errors are left to
    the real frames, a user's interrupt passes."""
    try:
        hook = getattr(associator, "warm_up", None)   # Associator subclasses have one; other plugins need not
        if callable(hook):
            hook(tiny_problem())
        else:
            associator.associate(tiny_problem())
    except BaseException as exc:  # noqa: BLE001
        if user_interrupt(exc):
            raise


def load_source(source, cache_dir: Path | None) -> None:
    """Read a simulated source's sequence (from ``cache_dir`` when named) before its frames are
    asked for."""
    load = getattr(source, "load", None)
    if callable(load):
        load(cache_dir)


class Problems:
    """The open loop's problem and truth per frame, built when first asked for, checked whole and
    kept for the run's other methods."""

    def __init__(self, track, source, run) -> None:
        self.track, self.source, self.run = track, source, run
        self._built: dict[int, tuple[Problem, FrameTruth]] = {}

    def __len__(self) -> int:
        return len(self.source)

    def __getitem__(self, k: int) -> tuple[Problem, FrameTruth]:
        if k not in self._built:
            with for_every_method():   # built once for all the run's methods: each depends on it
                problem, truth = self.track.problem(self.source, k, self.run)
            self._built[k] = checked_frame(self.track.name, k, problem, truth)
        return self._built[k]


def checked_frame(track: str, k: int, problem: Problem, truth: FrameTruth) -> tuple[Problem, FrameTruth]:
    """``(problem, truth)`` of frame ``k`` once ``Problem.validate`` and ``checked_truth`` pass,
    else a ``UserError`` naming track and frame (every method's input: the command stops, exit 2)."""
    try:
        problem.validate()
    except ValueError as exc:
        raise UserError(f"the {track} track's frame {k} is invalid: {exc}") from None
    return problem, checked_truth(track, k, problem, truth)


def checked_truth(track: str, k: int, problem: Problem, truth: FrameTruth) -> FrameTruth:
    """``truth`` once ``FrameTruth.validate(problem)`` passes, else a ``UserError`` naming track and
    frame."""
    try:
        if not isinstance(truth, FrameTruth):
            raise ValueError(f"its truth is a {type(truth).__name__}, not a FrameTruth")
        return truth.validate(problem)
    except ValueError as exc:
        raise UserError(f"the {track} track's frame {k} is invalid: {exc}") from None


def private_copy(problem: Problem) -> Problem:
    """A read-only copy of ``problem`` with arrays of its own: what one ``associate`` call gets."""
    out = copy.copy(problem)
    for name in _ARRAYS + tuple(d for d in DESCRIPTOR_FIELDS if getattr(problem, d) is not None):
        arr = getattr(problem, name).copy()
        arr.flags.writeable = False
        object.__setattr__(out, name, arr)
    return out


def user_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is a real Ctrl-C, a ``KeyboardInterrupt`` where SIGINT is not ignored (in a
    worker one can only be the method's)."""
    return isinstance(exc, KeyboardInterrupt) and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN


def describe(exc: BaseException) -> str:
    """One line for the ``error`` column: ``Type: message``."""
    return f"{type(exc).__name__}: {exc}".replace("\n", " ")[:300]


def method_diagnostics(associator, problem: Problem) -> dict:
    """What ``info`` says of the last call: ``timed_out``, ``proven_optimal`` (1.0, 0.0, NaN
    unsaid), a soft method's validated ``marginals``."""
    info = getattr(associator, "info", None) or {}
    proven = info.get("proven_optimal")
    if proven is not None and not isinstance(proven, (bool, np.bool_)):
        raise ValueError(f"info['proven_optimal'] must be True, False or absent, got {proven!r}")
    out = {"timed_out": bool(info.get("timed_out", False)),
           "proven_optimal": float("nan") if proven is None else float(proven)}
    if getattr(associator, "soft", False):
        out["marginals"] = soft_marginals(info.get("marginals"), problem)
    return out


def soft_marginals(marginals, problem: Problem) -> np.ndarray:
    """``info["marginals"]`` as (n, m + 1) probabilities with rows summing to 1 (1e-6), else a
    ``ValueError`` failing the frame."""
    shape = (problem.n, problem.m + 1)
    beta = np.array(marginals, dtype=np.float64) if marginals is not None else None
    if beta is None or beta.shape != shape:
        raise ValueError(f"a soft associator must set info['marginals'] of shape {shape}, "
                         f"got {None if beta is None else beta.shape}")
    if not np.all(np.isfinite(beta)) or beta.min(initial=0.0) < -1e-12 or beta.max(initial=0.0) > 1 + 1e-12:
        raise ValueError("info['marginals'] must hold probabilities in [0, 1] (no NaN)")
    if beta.size and np.abs(beta.sum(axis=1) - 1.0).max() > 1e-6:
        raise ValueError("each row of info['marginals'] must sum to 1")
    return beta


def call_method(associator, problem: Problem) -> tuple[np.ndarray | None, float, dict, str]:
    """``associate`` on a private copy of ``problem``, timed alone: (association validated against
    the pristine problem, runtime_s, diagnostics, error); whatever its code raises fails the frame."""
    start = time.perf_counter()
    try:
        raw = associator.associate(private_copy(problem))
        runtime = time.perf_counter() - start
    except BaseException as exc:  # noqa: BLE001 - SystemExit too: a plugin must not end the run
        if user_interrupt(exc):
            raise
        return None, time.perf_counter() - start, {}, describe(exc)
    try:
        association = validate_association(raw, problem)
        diagnostics = method_diagnostics(associator, problem)
    except BaseException as exc:  # noqa: BLE001
        if user_interrupt(exc):
            raise
        return None, runtime, {}, describe(exc)
    return association, runtime, diagnostics, ""


def failed_record(k: int, problem: Problem, truth: FrameTruth, error: str, runtime: float) -> dict:
    """Record of frame ``k`` that failed: scored as if no pairing was returned, with its error."""
    return {"frame": k, **unscored_frame(problem, truth), "timed_out": False, "proven_optimal": float("nan"),
            "true_mass": float("nan"), "runtime_s": runtime, "error": error, "association": [NO_MATCH] * problem.n}


def guarded_build(make: Callable[[], object]) -> tuple[object | None, str]:
    """``(make(), "")``, or ``(None, error)`` when the method's own constructor fails; ``UserError``
    and a real Ctrl-C propagate."""
    try:
        return make(), ""
    except UserError:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's constructor is plugin code
        if user_interrupt(exc):
            raise
        return None, describe(exc)


def _build(method: str, params: dict):
    """The associator, or (None, error) when its own constructor fails (``guarded_build``)."""
    return guarded_build(lambda: make_associator(method, **params))


def frame_records(problems: Problems, method: str, params: dict,
                  time_limit_s: float = float("inf"), first: int = 0, faults: dict | None = None,
                  on_call: Callable[..., None] = lambda k, limit, whose=METHOD: None) -> Iterator[dict]:
    """Per-frame records of ``method`` on ``problems[first:]``; a method that raises, exits or
    answers invalidly fails that frame (``error``). ``on_call(k, limit_s, whose)`` hears each call
    first, so a supervisor can kill it past its limit: ``k = WARM_UP`` for building and warming the
    method (``WARM_UP_FACTOR`` times the limit), ``whose = TRACK`` before the track builds frame
    ``k``'s problem (a hang there is the run's failure, not the method's). ``faults``: frames
    already known failed (``WARM_UP``: all), recorded without calling the method.
    """
    faults = faults or {}
    if WARM_UP in faults:  # the method could not even start: every frame fails with that error
        for k in range(first, len(problems)):
            yield failed_record(k, *problems[k], *faults.get(k, (faults[WARM_UP][0], 0.0)))
        return
    on_call(WARM_UP, WARM_UP_FACTOR * time_limit_s)
    associator, error = _build(method, params)
    if associator is not None:
        warm_up(associator)
    for k in range(first, len(problems)):
        on_call(k, WARM_UP_FACTOR * time_limit_s, TRACK)
        problem, truth = problems[k]
        if k in faults or associator is None:
            yield failed_record(k, problem, truth, *(faults.get(k) or (error, 0.0)))
            continue
        on_call(k, time_limit_s)
        association, runtime, diagnostics, error_k = call_method(associator, problem)
        if association is None:
            yield failed_record(k, problem, truth, error_k, runtime)
            continue
        marginals = diagnostics.pop("marginals", None)
        mass = true_mass(marginals, truth.association) if marginals is not None else float("nan")
        yield {"frame": k, **score_frame(problem, truth, association), **diagnostics, "true_mass": mass,
               "runtime_s": runtime, "error": "", "association": association.tolist()}


@dataclass
class GuardedCalls:
    """The plugin boundary of a track's own frame loop (``MethodCalls``): each call announced with
    its limit, timed, its exceptions (but Ctrl-C) the frame's error."""

    time_limit_s: float
    faults: dict
    on_call: Callable[[int, float], None]

    def build(self, make: Callable[[], object]) -> tuple[object | None, str]:
        if WARM_UP in self.faults:   # building it died or hung in an earlier worker
            return None, self.faults[WARM_UP][0]
        self.on_call(WARM_UP, WARM_UP_FACTOR * self.time_limit_s)
        return guarded_build(make)

    def call(self, k: int, fn: Callable[[], object]) -> tuple[object | None, float, str]:
        self.on_call(k, self.time_limit_s)
        start = time.perf_counter()
        try:
            out = fn()
        except BaseException as exc:  # noqa: BLE001 - SystemExit too: a plugin must not end the run
            if user_interrupt(exc):
                raise
            return None, time.perf_counter() - start, describe(exc)
        return out, time.perf_counter() - start, ""


def summarize_run(track, frames) -> dict:
    """A run's summary row: the track's own, else the shared metrics and the track's ``RunScores``."""
    if has(track, OwnFrames):
        return track.summarize(frames)
    return summarize(frames) | (track.run_scores(frames) if has(track, RunScores) else {})


def describe_run(track, run) -> tuple[dict, str]:
    """Columns saying how a run was made, and the same in words: the track's own, else the loop
    (``open``, or the estimator's mode and name)."""
    if has(track, OwnFrames):
        return track.describe(run)
    return {"loop": run.estimator.mode if run.loop else "open"}, loop_words(run)
