"""Run a suite's jobs: one worker process at a time, several (``--jobs N``), or on a dask cluster.

Every job runs in a worker process (``sandbox.py``): a method call past its time limit, or a
method that dies or exits, fails that frame and the job goes on; an interrupt kills the workers
at once. Each job's results are stored by ``jobstore`` under ``<out>/jobs/`` as it finishes; a
job whose stored files are complete and verified is skipped, so an interrupted sweep resumes
where it stopped.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from ..atomic import ensure_dir
from ..errors import UserError
from .config import run_spec
from .jobstore import load_job, store_job
from .records import frame_table
from .runner import summarize_run
from .sandbox import Supervisor, Task, TaskFailed
from .suite import Job, Suite

EXECUTORS = ("local", "dask")
def kept_frames(per_frame: pd.DataFrame, label: dict, columns: tuple[str, ...]) -> pd.DataFrame:
    """The leaderboard's per-frame rows of one run: ``label``'s columns, ``frame`` and those of the
    track's ``columns`` (``Columns.frames``) the run has."""
    kept = ["frame"] + [c for c in columns if c in per_frame]
    return per_frame.assign(**label)[list(label) + kept]


def job_task(job: Job, cache_dir: str | None = None) -> Task:
    """The worker task of ``job``: its runs (difficulty, resolved spec) and its methods."""
    return Task(f"{job.name} seed {job.seed}", tuple((f"{job.name}/{d} seed {job.seed}", run_spec(cfg))
                                                      for d, cfg in job.runs),
                tuple((m.label, m.method, dict(m.params)) for m in job.methods), cache_dir)


def job_result(job: Job, records: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Summaries (one row per difficulty × method) and per-frame (n, runtime) of one job, from
    the worker's records by (difficulty index, method index) (each an iterable in frame order:
    a ``RecordSpool``)."""
    summaries, frames = [], []
    for r, (difficulty, cfg) in enumerate(job.runs):
        spec = run_spec(cfg)
        track = spec.track_impl
        for mi, entry in enumerate(job.methods):
            per_frame = frame_table(records[(r, mi)])
            errors = sorted(set(per_frame["error"]) - {""})
            label = {"scenario": f"{job.name}/{difficulty}", "scene": job.name, "difficulty": difficulty,
                     "method": entry.label, "seed": job.seed}
            summaries.append({**label, **summarize_run(track, per_frame), "error": errors[0] if errors else ""})
            frames.append(kept_frames(per_frame, label, track.columns(spec.loop).frames))
    return pd.DataFrame(summaries), pd.concat(frames, ignore_index=True)


class _Bar(tqdm):
    """The sweep's progress bar, without tqdm's monitor thread: a process with no other thread
    can fork its workers (``sandbox._context``), which is much faster than a forkserver."""

    monitor_interval = 0


def _report(line: str) -> None:
    tqdm.write(f"assocbench: {line}", file=sys.stderr)


def run_job(job: Job, cache_dir: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Summaries and per-frame records of one job, run in a worker process (see ``job_result``)."""
    out = []   # made while the task's spooled records are still open
    Supervisor(1, _report).run([job_task(job, cache_dir)], lambda _, records: out.append(job_result(job, records)))
    return out[0]


def _dask_client(address: str | None):
    try:
        from dask.distributed import Client
    except ImportError:
        raise UserError("the dask executor needs the optional extra: pip install 'assocbench[dask]' "
                        "(from a clone: pip install '.[dask]')") from None
    if not address:
        raise UserError("--executor dask needs --address tcp://scheduler:8786")
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise UserError(f"cannot reach dask scheduler {address}: {exc}") from None


def _run_dask(todo: list[Job], out: Path, client, cache_dir: str | None, bar: tqdm) -> None:
    """Run ``todo`` on the dask cluster of ``client`` (opened by ``_dask_client``), storing each
    job as it finishes."""
    from dask.distributed import as_completed as dask_completed  # importable: the client exists

    with client:
        futures = {client.submit(run_job, j, cache_dir, pure=False): j for j in todo}
        for fut in dask_completed(futures):
            store_job(out, futures[fut], fut.result())
            bar.update()


def _run_local(todo: list[Job], out: Path, jobs: int, cache_dir: str | None, bar: tqdm) -> None:
    """Run ``todo`` in at most ``jobs`` worker processes, storing each job as it finishes; a job
    that fails outside any method call is named, the others still run, then ``TaskFailed``."""
    if jobs == 1:
        failed = []
        for j in todo:
            try:
                store_job(out, j, run_job(j, cache_dir))
            except TaskFailed as exc:
                failed.append(exc)
            bar.update()
        if failed:
            raise TaskFailed(f"{len(failed)} of {len(todo)} job(s) failed; first: {failed[0]}")
        return
    tasks = [job_task(j, cache_dir) for j in todo]
    job_of = {id(t): j for t, j in zip(tasks, todo)}

    def finished(task: Task, records: dict) -> None:
        store_job(out, job_of[id(task)], job_result(job_of[id(task)], records))
        bar.update()

    Supervisor(jobs, _report).run(tasks, finished)


def run_suite(suite: Suite, out: Path, jobs: int = 1, executor: str = "local", address: str | None = None,
              cache_dir: str | None = None, progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run every job not already stored under ``out``; return all summaries and frame records."""
    if executor not in EXECUTORS:
        raise UserError(f"unknown executor {executor!r}: choose one of {', '.join(EXECUTORS)}")
    if jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {jobs}")
    # the cluster is reached before anything is written: a missing extra, no address or an
    # unreachable scheduler is one line and leaves no output folder behind
    client = _dask_client(address) if executor == "dask" else None
    ensure_dir(out / "jobs")
    done = [load_job(out, j) for j in suite.jobs]
    todo = [j for j, d in zip(suite.jobs, done) if d is None]
    bar = _Bar(total=len(suite.jobs), initial=len(suite.jobs) - len(todo), desc=f"{suite.name}",
               unit="job", disable=not progress or not sys.stderr.isatty())  # no bars in logs
    try:
        if executor == "dask":
            _run_dask(todo, out, client, cache_dir, bar)
        else:
            _run_local(todo, out, jobs, cache_dir, bar)
    finally:
        bar.close()
    parts = [d or _reloaded(out, j) for j, d in zip(suite.jobs, done)]
    summaries = pd.concat([s for s, _ in parts], ignore_index=True)
    return summaries, pd.concat([f for _, f in parts], ignore_index=True)


def _reloaded(out: Path, job: Job) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A job stored by this sweep, read back verified (so every job's frames have CSV dtypes)."""
    result = load_job(out, job)
    if result is None:
        raise UserError(f"job {job.name} seed {job.seed} was stored under {out / 'jobs'} but cannot be read back; "
                        "run again to recompute it")
    return result
