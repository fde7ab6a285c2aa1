"""One run: a cached sequence, a belief per frame, one associator, scored frame by frame."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from ..association.problem import validate_association
from ..associators.registry import make_associator
from ..belief.camera_belief import BeliefConfig, make_problem
from ..scoring.aggregate import summarize
from ..scoring.metrics import score_frame, unscored_frame
from ..sim.sequence import Sequence, load_sequence
from .config import RunSpec


def associate_frames(seq: Sequence, belief: BeliefConfig, seed: int, method: str, params: dict,
                     frames: range | None = None) -> pd.DataFrame:
    """Per-frame records of ``method`` on ``seq``. A method that raises or returns an invalid
    association is recorded as failed on that frame (``error``) and the run goes on."""
    associator = make_associator(method, **params)
    rows = []
    for k in frames if frames is not None else range(len(seq)):
        problem, truth = make_problem(seq, k, belief, seed)
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
    frames = associate_frames(seq, spec.belief, spec.seed, spec.method, spec.params)
    return frames, summarize(frames)
