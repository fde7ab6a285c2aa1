"""Run a suite's missing runs: one worker at a time, several (``--jobs N``), or on a dask cluster.

The stored unit is one run, a method on one scene, seed and difficulty (``suite.Run``). A sweep
computes only the runs not stored under ``<out>/runs/`` (``runstore``) or stored from other inputs:
adding a method computes its runs, removing one nothing, changing one method's parameters that
method. The missing runs of one cell form one worker task (``sandbox.Task``), which reads the
sequence and builds each problem once for all its methods. Each run is stored as its task finishes,
with the inputs its worker imported (``inputs.py``), so an interrupted sweep resumes; a run whose
code was saved while it ran is returned but not stored.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from itertools import zip_longest
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from ..atomic import ensure_dir
from ..errors import UserError
from .inputs import ImportGraph, RunInputs, Stale, run_inputs, run_roots
from .records import frame_table
from .runner import summarize_run
from .runstore import FOLDER, as_read_back, lookup, store_run
from .sandbox import Supervisor, Task, TaskFailed
from .suite import Run, Suite

EXECUTORS = ("local", "dask")
Result = tuple[pd.DataFrame, pd.DataFrame]   # a run's summary row and per-frame records, unlabelled


def cell_task(runs: list[Run], cache_dir: str | None = None) -> Task:
    """The worker task of one cell's ``runs``: the cell's run and the methods."""
    cell = runs[0].cell
    name = f"{cell.scenario} seed {cell.seed}"
    return Task(name, ((name, runs[0].spec),), tuple((r.entry.label, r.entry.method, dict(r.entry.params))
                                                      for r in runs), cache_dir)


def run_result(run: Run, records) -> Result:
    """A run's summary row and the per-frame columns of its track, from the worker's records."""
    per_frame = frame_table(records)
    errors = sorted(set(per_frame["error"]) - {""})
    summary = pd.DataFrame([{**summarize_run(run.spec.track_impl, per_frame), "error": errors[0] if errors else ""}])
    kept = ["frame"] + [c for c in run.spec.track_impl.columns(run.spec.loop).frames if c in per_frame]
    return summary, per_frame[kept]


def cell_results(runs: list[Run], records: dict, imports: dict, graph: ImportGraph) -> list[tuple[Result, RunInputs | str]]:
    """Each run's result and its inputs (``inputs.run_inputs``), or why they cannot be stored."""
    out = []
    for mi, run in enumerate(runs):
        out.append((run_result(run, records[(0, mi)]), _inputs(run, imports.get((0, mi)), graph)))
    return out


def _inputs(run: Run, report: dict | None, graph: ImportGraph) -> RunInputs | str:
    """A run's inputs from its worker's ``report``, or why they cannot be stored."""
    if report is None:
        return "its worker sent no record of what it imported"
    roots, installed = run_roots(run.spec, run.entry.method)
    try:
        return run_inputs(graph, roots, report, installed)
    except Stale as exc:
        return str(exc)


class _Bar(tqdm):
    """The sweep's progress bar without tqdm's monitor thread, so workers can fork
    (``sandbox._context``)."""

    monitor_interval = 0


def _report(line: str) -> None:
    tqdm.write(f"assocbench: {line}", file=sys.stderr)


def run_cell(runs: list[Run], cache_dir: str | None = None,
             graph: ImportGraph | None = None) -> list[tuple[Result, RunInputs | str]]:
    """Results and inputs of one cell's ``runs`` in a worker (``graph``: files already read,
    shared)."""
    graph = graph or ImportGraph()
    out = []   # made while the task's spooled records are still open
    Supervisor(1, _report).run([cell_task(runs, cache_dir)],
                               lambda _, records, imports: out.extend(cell_results(runs, records, imports, graph)))
    return out


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


def _run_dask(todo: list[list[Run]], keep: Callable, client, cache_dir: str | None) -> None:
    """Run each cell's ``todo`` on the dask cluster of ``client`` (opened by ``_dask_client``),
    keeping each as it finishes."""
    from dask.distributed import as_completed as dask_completed  # importable: the client exists

    with client:
        futures = {client.submit(run_cell, runs, cache_dir, pure=False): runs for runs in todo}
        for fut in dask_completed(futures):
            keep(futures[fut], fut.result())


def _run_local(todo: list[list[Run]], keep: Callable, jobs: int, cache_dir: str | None) -> None:
    """Run each cell's ``todo`` in at most ``jobs`` workers, keeping each as it finishes; a task
    failing outside a method call is named, the rest run, then ``TaskFailed``."""
    graph = ImportGraph()
    if jobs == 1:
        failed = []
        for runs in todo:
            try:
                keep(runs, run_cell(runs, cache_dir, graph))
            except TaskFailed as exc:
                failed.append(exc)
        if failed:
            raise TaskFailed(f"{len(failed)} of {len(todo)} task(s) failed; first: {failed[0]}")
        return
    tasks = [cell_task(runs, cache_dir) for runs in todo]
    runs_of = {id(t): runs for t, runs in zip(tasks, todo)}
    Supervisor(jobs, _report).run(tasks, lambda task, records, imports: keep(
        runs_of[id(task)], cell_results(runs_of[id(task)], records, imports, graph)))


def missing_cells(suite: Suite, out: Path) -> tuple[dict[Run, Result], list[list[Run]], list[str]]:
    """The reusable stored results, the other runs grouped by cell (``in_turns``), and why stored
    runs are out of date."""
    done, todo, changed = {}, {}, []
    for run in suite.runs:
        result, why = lookup(out, run)
        if result is not None:
            done[run] = result
        else:
            todo.setdefault(run.cell, []).append(run)
            changed += [why] if why else []
    return done, in_turns(list(todo.values())), changed


def in_turns(tasks: list[list[Run]]) -> list[list[Run]]:
    """``tasks`` taking one of each sequence in turn, so tasks run side by side make different
    sequences (not one render twice on a cold cache)."""
    by_source: dict[str, list] = {}
    for runs in tasks:
        by_source.setdefault(runs[0].spec.source.key, []).append(runs)
    return [runs for turn in zip_longest(*by_source.values()) for runs in turn if runs is not None]


def run_suite(suite: Suite, out: Path, jobs: int = 1, executor: str = "local", address: str | None = None,
              cache_dir: str | None = None, progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Compute the runs of ``suite`` not stored under ``out``, storing each as it finishes; return
    every run's summary and frames, labelled, in suite order."""
    if executor not in EXECUTORS:
        raise UserError(f"unknown executor {executor!r}: choose one of {', '.join(EXECUTORS)}")
    if jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {jobs}")
    # the cluster is reached before anything is written: a missing extra, no address or an
    # unreachable scheduler is one line and leaves no output folder behind
    client = _dask_client(address) if executor == "dask" else None
    ensure_dir(out / FOLDER)
    done, todo, changed = missing_cells(suite, out)
    if changed:
        _report(f"{len(changed)} stored run(s) are out of date ({changed[0]}); recomputing them")
    bar = _Bar(total=len(suite.runs), initial=len(done), desc=f"{suite.name}", unit="run",
               disable=not progress or not sys.stderr.isatty())  # no bars in logs

    def keep(runs: list[Run], results: list[tuple[Result, RunInputs | str]]) -> None:
        for run, (result, inputs) in zip(runs, results):
            if isinstance(inputs, str):
                _report(f"{run.name} is not stored: {inputs} (it is recomputed next time)")
            else:
                store_run(out, run, result, inputs)
            done[run] = as_read_back(result)
        bar.update(len(runs))

    try:
        if executor == "dask":
            _run_dask(todo, keep, client, cache_dir)
        else:
            _run_local(todo, keep, jobs, cache_dir)
    finally:
        bar.close()
    parts = [_labelled(run, done[run]) for run in suite.runs]
    return pd.concat([s for s, _ in parts], ignore_index=True), pd.concat([f for _, f in parts], ignore_index=True)


def _labelled(run: Run, result: Result) -> Result:
    """A run's summary and frames with the suite's labels first (scenario, scene, difficulty,
    method, seed)."""
    summary, frames = result
    label = run.label
    return (pd.concat([pd.DataFrame([label] * len(summary)), summary.reset_index(drop=True)], axis=1),
            frames.assign(**label)[list(label) + list(frames.columns)])

