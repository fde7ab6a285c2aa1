"""One run: a cached sequence, a belief per frame, one associator, scored frame by frame."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..association.problem import Problem, validate_association
from ..associators.registry import make_associator
from ..belief.camera_belief import BeliefConfig, FrameTruth, make_problem
from ..scoring.aggregate import summarize
from ..scoring.metrics import score_frame, unscored_frame
from ..sim.sequence import Sequence, load_sequence
from .config import RunSpec


def warm_up(associator) -> None:
    """Run ``associator`` once on a tiny problem so that loading compiled kernels (numba's
    cache, a plugin's own JIT) is not timed as the first frame's runtime. Errors are left to
    the real frames to report."""
    tiny = Problem(np.array([[0.0, 0.0], [5.0, 0.0]]), np.repeat(np.eye(2)[None], 2, axis=0),
                   np.array([[0.2, 0.1], [5.1, 0.2]]), np.eye(4), volume=100.0)
    try:
        associator.associate(tiny)
    except Exception:  # noqa: BLE001
        pass


def frame_problems(seq: Sequence, belief: BeliefConfig, seed: int) -> list[tuple[Problem, FrameTruth]]:
    """The problem and truth of every frame; built once and shared by every method of a sweep."""
    return [make_problem(seq, k, belief, seed) for k in range(len(seq))]


def associate_frames(problems: list[tuple[Problem, FrameTruth]], method: str, params: dict) -> pd.DataFrame:
    """Per-frame records of ``method`` on ``problems``. A method that raises or returns an invalid
    association is recorded as failed on that frame (``error``) and the run goes on."""
    associator = make_associator(method, **params)
    warm_up(associator)
    rows = []
    for k, (problem, truth) in enumerate(problems):
        error, timed_out = "", False
        start = time.perf_counter()
        try:
            raw = associator.associate(problem)
            runtime = time.perf_counter() - start
            association = validate_association(raw, problem)
            record = score_frame(problem, truth, association)
            timed_out = bool(getattr(associator, "info", {}).get("timed_out", False))
        except Exception as exc:  # noqa: BLE001 - a plugin's failure must not stop a sweep
            runtime = time.perf_counter() - start
            error = f"{type(exc).__name__}: {exc}".replace("\n", " ")[:300]
            record = unscored_frame(problem, truth)
        rows.append({"frame": k, **record, "timed_out": timed_out, "runtime_s": runtime, "error": error})
    return pd.DataFrame(rows)


def execute(spec: RunSpec, cache_dir: Path | None = None) -> tuple[pd.DataFrame, dict]:
    """Run ``spec``: per-frame records and the summary."""
    seq = load_sequence(spec.sequence, cache_dir)
    frames = associate_frames(frame_problems(seq, spec.belief, spec.seed), spec.method, spec.params)
    return frames, summarize(frames)
