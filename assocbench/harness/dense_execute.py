"""A dense run from spec to tables: per-frame records, the summary, and the files a user keeps."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..tracks.dense.summary import poses, summarize_dense
from ..scoring.trajectory import tum_text
from ..sim.ply import write_ply
from .dense_run import run_dense
from ..tracks.dense.spec import DenseRunSpec


def execute_dense(spec: DenseRunSpec, cache_dir: Path | None = None) -> tuple[pd.DataFrame, dict, dict]:
    """Run ``spec``: per-frame records (a DataFrame), the summary row and the end-of-run facts."""
    records, end = run_dense(spec, cache_dir)
    frames = pd.DataFrame(records)
    return frames, summarize_dense(frames, end), end


def dense_writers(frames: pd.DataFrame, end: dict, out: Path, title: str) -> dict:
    """Writers of ``truth.txt`` / ``estimate.txt`` (TUM), ``map.ply`` (the fused map with its
    weight and distance to the true surface, mm) and ``map.png`` (its top view)."""
    from ..tracks.dense.plots import map_figure

    stamps = frames["frame"].to_numpy(float)
    (R_true, p_true), (R_est, p_est) = poses(frames, "true_"), poses(frames, "est_")
    pmap, error_mm = end["map"], 1000 * end["map_error"]
    truth, estimate = tum_text(stamps, R_true, p_true, "truth"), tum_text(stamps, R_est, p_est, "estimate")
    panel = {"positions": pmap.positions, "error_mm": error_mm, "p_true": p_true, "p_est": p_est, "title": title}
    return {out / "truth.txt": lambda p: Path(p).write_text(truth),
            out / "estimate.txt": lambda p: Path(p).write_text(estimate),
            out / "map.ply": lambda p: write_ply(p, pmap.positions, pmap.normals,
                                                 {"weight": pmap.weights, "error_mm": error_mm}),
            out / "map.png": lambda p: map_figure([panel], p, columns=1)}

