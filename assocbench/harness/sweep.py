"""Run a suite's jobs: in this process, in local processes (``--jobs N``) or on a dask cluster.

Each job's results are stored by ``jobstore`` under ``<out>/jobs/``; a job whose stored files
are complete and verified is skipped, so an interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from ..atomic import ensure_dir
from ..errors import UserError
from ..scoring.aggregate import summarize
from ..sim.sequence import load_sequence
from .config import run_spec
from .jobstore import load_job, store_job
from .runner import associate_frames, frame_problems
from .suite import Job, Suite

EXECUTORS = ("local", "dask")


def run_job(job: Job, cache_dir: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Summaries (one row per difficulty × method) and per-frame (n, runtime) of one job."""
    summaries, frames = [], []
    for difficulty, cfg in job.runs:
        spec = run_spec(cfg)
        seq = load_sequence(spec.sequence, Path(cache_dir) if cache_dir else None)
        problems = frame_problems(seq, spec.belief, spec.seed)
        for entry in job.methods:
            per_frame = associate_frames(problems, entry.method, entry.params)
            errors = sorted(set(per_frame["error"]) - {""})
            label = {"scenario": f"{job.scene}/{difficulty}", "scene": job.scene, "difficulty": difficulty,
                     "method": entry.label, "seed": job.seed}
            summaries.append({**label, **summarize(per_frame), "error": errors[0] if errors else ""})
            frames.append(per_frame.assign(**label)[list(label) + ["frame", "n", "m", "runtime_s"]])
    return pd.DataFrame(summaries), pd.concat(frames, ignore_index=True)


def _dask_client(address: str | None):
    try:
        from dask.distributed import Client
    except ImportError:
        raise UserError("the dask executor needs the optional extra: pip install 'assocbench[dask]'") from None
    if not address:
        raise UserError("--executor dask needs --address tcp://scheduler:8786")
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise UserError(f"cannot reach dask scheduler {address}: {exc}") from None


def run_suite(suite: Suite, out: Path, jobs: int = 1, executor: str = "local", address: str | None = None,
              cache_dir: str | None = None, progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run every job not already stored under ``out``; return all summaries and frame records."""
    if executor not in EXECUTORS:
        raise UserError(f"unknown executor {executor!r}: choose one of {', '.join(EXECUTORS)}")
    if jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {jobs}")
    ensure_dir(out / "jobs")
    done = [load_job(out, j) for j in suite.jobs]
    todo = [j for j, d in zip(suite.jobs, done) if d is None]
    bar = tqdm(total=len(suite.jobs), initial=len(suite.jobs) - len(todo), desc=f"{suite.name}",
               unit="job", disable=not progress)
    if executor == "dask":
        from dask.distributed import as_completed as dask_completed

        with _dask_client(address) as client:
            futures = {client.submit(run_job, j, cache_dir, pure=False): j for j in todo}
            for fut in dask_completed(futures):
                store_job(out, futures[fut], fut.result())
                bar.update()
    elif jobs == 1:
        for j in todo:
            store_job(out, j, run_job(j, cache_dir))
            bar.update()
    else:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
            futures = {pool.submit(run_job, j, cache_dir): j for j in todo}
            for fut in as_completed(futures):
                store_job(out, futures[fut], fut.result())
                bar.update()
    bar.close()
    parts = [d or _reloaded(out, j) for j, d in zip(suite.jobs, done)]
    summaries = pd.concat([s for s, _ in parts], ignore_index=True)
    return summaries, pd.concat([f for _, f in parts], ignore_index=True)


def _reloaded(out: Path, job: Job) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A job stored by this sweep, read back verified (so every job's frames have CSV dtypes)."""
    result = load_job(out, job)
    if result is None:
        raise UserError(f"job {job.scene} seed {job.seed} was stored under {out / 'jobs'} but cannot be read back; "
                        "run again to recompute it")
    return result
