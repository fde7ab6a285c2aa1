"""One run: a cached sequence, a belief per frame, one associator, scored frame by frame.

The frame loop (``frame_records``) runs inside a worker process (``sandbox.py``), which is what
lets the parent enforce a time limit and survive a method that dies or exits; ``sandbox.execute`` runs
it there. The plugin boundary is ``call_method``: anything a method raises, ``SystemExit`` included,
is that frame's failure, and every call gets its own copy of the problem, so a method that
edits its problem in place can change neither the scoring nor what later methods see.
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
    """Run ``associator`` once on a tiny problem so that loading compiled kernels (numba's
    cache, a plugin's own JIT) is not timed as the first frame's runtime. Errors are left to
    the real frames to report, ``SystemExit`` included; a user's interrupt is not swallowed."""
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
    """Read a simulated source's sequence (from ``cache_dir`` when the task names one) before its
    frames are asked for; a recorded source reads its frames itself."""
    load = getattr(source, "load", None)
    if callable(load):
        load(cache_dir)


class Problems:
    """The open loop's problem and truth of each frame of a run, built when first asked for
    (``track.problem``), checked whole before any method sees it (``checked_frame``: the problem and
    the truth against it), and kept for the run's other methods: a worker builds each frame once,
    whatever the methods."""

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
    """``(problem, truth)`` of frame ``k`` once ``Problem.validate`` passes and the truth is
    ``checked_truth``; else a ``UserError`` naming the track and frame. A track's open-loop frame
    is the benchmark's input, the same for every method: nothing can be measured against it, so
    the command stops (exit 2) rather than score each method against pairs that cannot exist."""
    try:
        problem.validate()
    except ValueError as exc:
        raise UserError(f"the {track} track's frame {k} is invalid: {exc}") from None
    return problem, checked_truth(track, k, problem, truth)


def checked_truth(track: str, k: int, problem: Problem, truth: FrameTruth) -> FrameTruth:
    """``truth`` once ``FrameTruth.validate(problem)`` passes; else a ``UserError`` naming the
    track and frame (see ``checked_frame``)."""
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
    """Whether ``exc`` is a real Ctrl-C, to be let through the plugin boundary: a
    ``KeyboardInterrupt`` where SIGINT is not ignored. A worker ignores SIGINT (its parent handles
    interrupts), so there a ``KeyboardInterrupt`` can only come from the method: a failure."""
    return isinstance(exc, KeyboardInterrupt) and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN


def describe(exc: BaseException) -> str:
    """One line for the ``error`` column: ``Type: message``."""
    return f"{type(exc).__name__}: {exc}".replace("\n", " ")[:300]


def method_diagnostics(associator, problem: Problem) -> dict:
    """What a method's ``info`` says about the call just made: ``timed_out`` (bool),
    ``proven_optimal`` (1.0 or 0.0 where the method says, NaN where it does not) and, for a
    soft associator, its ``marginals`` (validated: ``soft_marginals``)."""
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
    """A soft associator's ``info["marginals"]`` as an (n, m + 1) float array of probabilities
    whose rows sum to 1 (within 1e-6); anything else is the frame's failure (``ValueError``)."""
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
    the pristine problem, runtime_s, ``method_diagnostics``, error). Everything the method raises,
    and any code of its that validation runs (``__array__``, an ``info`` property), is the
    frame's failure."""
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
    """``(make(), "")``, or ``(None, error)`` when building a method fails in its own code; a bad
    name or parameter is the user's (``UserError`` propagates), and so is a real Ctrl-C."""
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
    """Per-frame records of ``method`` on ``problems[first:]``, one at a time. A method that raises,
    exits or returns an invalid association is recorded as failed on that frame (``error``).

    ``on_call(k, limit_s, whose)`` is told before each call (``k = WARM_UP`` for building the
    associator and warming it up, with ``WARM_UP_FACTOR`` times the limit), so that a supervising
    process can kill a call past its limit; ``whose`` is ``TRACK`` before the track builds frame
    ``k``'s problem (``WARM_UP_FACTOR`` times the limit too): a track that hangs there is the run's
    failure, not the method's. ``faults`` maps frame indices to (error, runtime_s) already known
    (``WARM_UP``: every frame): those frames are recorded failed without calling the method.
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
    """The plugin boundary for a track's own frame loop (``tracks.base.MethodCalls``): each call
    announced to the supervising process with its limit, timed, and anything it raises (but a
    real Ctrl-C) turned into the frame's error."""

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
    """The summary row of one run's per-frame records: the track's own (``OwnFrames``), else the
    shared metrics of association problems (``scoring.aggregate.summarize``) and the track's own
    scores of the run (``RunScores``)."""
    if has(track, OwnFrames):
        return track.summarize(frames)
    return summarize(frames) | (track.run_scores(frames) if has(track, RunScores) else {})


def describe_run(track, run) -> tuple[dict, str]:
    """Columns that say how a run was made, and the same in words: the track's own (``OwnFrames``),
    else the loop (``open``, or the estimator's mode and name in the closed loop)."""
    if has(track, OwnFrames):
        return track.describe(run)
    return {"loop": run.estimator.mode if run.loop else "open"}, loop_words(run)
