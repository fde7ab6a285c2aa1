"""Worker processes for method code: a per-call time limit, and methods that die, exit or hang fail
their frames instead of the run. The ``Supervisor`` runs each ``Task`` (one sequence's runs ×
methods) in a worker forked from a forkserver with the built-in kernels loaded. The worker announces
each call and sends each frame's record (scored in the worker against the pristine problem); when a
call overruns or the worker dies, the parent kills it, fails the frame and resumes at the next frame
in a fresh worker (same seed, same problems). Workers ignore SIGINT and SIGTERM, exit when the
parent is gone, and are killed with their process group, taking what their method started.
"""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from functools import partial
from multiprocessing.connection import wait
from pathlib import Path
from typing import NamedTuple

import pandas as pd
from tqdm import tqdm

from ..errors import UserError
from ..tracks.capabilities import OwnFrames, WarmUp, has
from ..tracks.registry import get_track
from . import imports
from .config import RunSpec
from .loop import loop_records
from .progress import RunProgress
from .records import RecordSpool, frame_table
from .runner import (
    METHOD,
    TRACK,
    WARM_UP,
    WARM_UP_FACTOR,
    GuardedCalls,
    Problems,
    describe,
    frame_records,
    load_source,
    summarize_run,
)

# modules the forkserver imports once; '__main__' (multiprocessing's default) spares each worker
# from re-running the main script, and the preload module loads the built-ins' kernels
WATCH_TICK_S = 0.5   # a watched run hears "tick" at least this often (the bar's clock moves)
PRELOAD = ["__main__", "assocbench.harness.worker_preload"]
SERVER_ENV = ("PYTHONSAFEPATH", "PYTHONPATH")   # set only while the forkserver starts
SAVED_ENV = "ASSOCBENCH_FORKSERVER_SAVED_ENV"   # the user's values of SERVER_ENV, for worker_preload
TRACKS_ENV = "ASSOCBENCH_FORKSERVER_TRACKS"     # the tracks the forkserver warms too, for worker_preload
METHODS_ENV = "ASSOCBENCH_FORKSERVER_METHODS"   # the methods whose built-in kernels it warms, for worker_preload
_GUARD = ("a script that runs assocbench from a process with threads (workers then come from a "
          "forkserver, which imports the script) must keep its top level under "
          "if __name__ == '__main__':")


@dataclass(frozen=True)
class Task:
    """One worker's work: the runs ``(label, RunSpec)`` on one sequence and the methods
    ``(label, method, params)``; ``name`` and labels for messages."""

    name: str
    runs: tuple
    methods: tuple
    cache_dir: str | None = None
    artifacts: str | None = None   # a folder for end-of-run files (one run: ``assocbench run``)


class TaskFailed(RuntimeError):
    """A task failed outside any method call (assocbench's own code, or its worker could not start)."""


@dataclass
class _Progress:
    """What the parent knows of a task: records per (run, method), calls failed in killed workers,
    where a fresh worker resumes."""

    records: dict = field(default_factory=dict)
    faults: dict = field(default_factory=dict)
    resume: tuple[int, int, int] = (0, 0, 0)
    imports: dict = field(default_factory=dict)   # (run, method) -> what its worker imported (imports.py)


# ---------------------------------------------------------------- worker side

def _worker(conn, task: Task, resume: tuple[int, int, int], faults: dict, environ: dict,
            replay: dict | None = None) -> None:
    """Worker entry: run ``task`` from ``resume``, streaming messages; always ``os._exit``, so a
    method's leftover threads cannot keep it alive."""
    _become_worker(environ)
    try:
        _run_task(conn.send, task, resume, faults, replay)
        conn.send(("done",))
    except UserError as exc:
        conn.send(("usererror", str(exc)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which names the task
        conn.send(("crash", describe(exc), traceback.format_exc()))
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001
                pass
        os._exit(0)


def _become_worker(environ: dict) -> None:
    """Its own session (so ``_kill_session`` kills all its method started), interrupts left to the
    parent, the parent's environment, exit with the parent."""
    try:
        os.setsid()
    except OSError:   # already a session's leader
        pass
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    os.environ.clear()
    os.environ.update(environ)
    # a progress bar's default lock is a named semaphore, which os._exit would leak
    tqdm.set_lock(threading.RLock())
    parent = mp.parent_process()
    if parent is not None:  # the sentinel turns ready when the parent dies, however it dies
        threading.Thread(target=_exit_with, args=(parent.sentinel,), daemon=True).start()


def _exit_with(sentinel) -> None:
    wait([sentinel])
    if os.getpgid(0) == os.getpid():   # its own session's leader: take the method's processes along
        os.killpg(0, signal.SIGKILL)
    os._exit(1)


def _kill_session(pid: int) -> None:
    """SIGKILL worker ``pid``'s process group, so processes its method started end with it; nothing
    when the group is gone."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _run_task(send: Callable, task: Task, resume: tuple[int, int, int], faults: dict,
              replay: dict | None = None) -> None:
    """Run the task's runs × methods from ``resume``, a closed loop replaying earlier frames from
    ``replay``."""
    cache = Path(task.cache_dir) if task.cache_dir else None
    log = imports.start()
    for r in range(resume[0], len(task.runs)):
        spec = task.runs[r][1]
        track = spec.track_impl
        log.begin_run()
        with log.for_every_method():
            warm_track(track)   # no-op where the parent warmed it and forked this worker
            load_source(spec.source, cache)
        problems = None if spec.loop or has(track, OwnFrames) else Problems(track, spec.source, spec)
        for mi in range(resume[1] if r == resume[0] else 0, len(task.methods)):
            log.begin_method()
            _, method, params = task.methods[mi]
            run = spec.with_method(method, params)
            first = resume[2] if (r, mi) == resume[:2] else 0
            announce = lambda k, limit, whose=METHOD, r=r, mi=mi: send(("call", r, mi, k, limit, whose))  # noqa: E731
            if problems is not None:
                records = frame_records(problems, method, params, spec.time_limit_s, first,
                                        faults.get((r, mi)), announce)
            elif spec.loop:
                records = loop_records(spec.source, run, first, faults.get((r, mi)), announce,
                                       replay if (r, mi) == resume[:2] else None)
            else:   # the track's own frame loop (its frames are not Problems)
                calls = GuardedCalls(spec.time_limit_s, faults.get((r, mi)) or {}, announce)
                records = track.records(spec.source, run, calls, first,
                                        Path(task.artifacts) if task.artifacts else None)
            for record in records:
                send(("frame", r, mi, record["frame"], record))
            send(("imports", r, mi, log.report()))


# ---------------------------------------------------------------- parent side

def _context(methods: Iterable[str], tracks: Iterable[str] = ()):
    """``fork`` when this process has no other thread (no lock inherited held; workers start with
    all loaded), else a forkserver started once with the built-ins warm."""
    methods, tracks = list(methods), list(tracks)
    if "fork" in mp.get_all_start_methods() and _single_threaded():
        warm_builtins(methods, tracks)  # here, so that every worker inherits the loaded kernels
        return mp.get_context("fork")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)  # no effect once the server runs: it is started once
    _start_forkserver(methods, tracks)
    return ctx


def _start_forkserver(methods: Iterable[str] = (), tracks: Iterable[str] = ()) -> None:
    """Start the forkserver on this process's ``sys.path``, warming the built-in associators among
    ``methods`` and the first task's ``tracks``, whose kernels its workers inherit (warming every
    built-in would compile kernels a run never calls; other methods and tracks warm in their
    worker). Python 3.11 starts it with ``python -c`` and ignores the ``sys_path`` handed to it, so
    the working folder came first and a clone's workers imported the clone's sources instead of the
    installed package: PYTHONSAFEPATH drops it and PYTHONPATH lists this process's path, for the
    server only (``worker_preload`` restores the user's values)."""
    from multiprocessing import forkserver

    saved = {key: os.environ.get(key) for key in SERVER_ENV}
    os.environ[SAVED_ENV] = json.dumps(saved)
    os.environ[TRACKS_ENV] = json.dumps(sorted(set(tracks)))
    os.environ[METHODS_ENV] = json.dumps(sorted(set(methods)))
    os.environ["PYTHONSAFEPATH"] = "1"
    os.environ["PYTHONPATH"] = os.pathsep.join(entry or os.getcwd() for entry in sys.path)
    try:
        forkserver.ensure_running()
    finally:
        restore_env(saved)
        os.environ.pop(SAVED_ENV, None)
        os.environ.pop(TRACKS_ENV, None)
        os.environ.pop(METHODS_ENV, None)


def restore_env(saved: dict) -> None:
    """Set (or unset, for None) each variable of ``saved``."""
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def _single_threaded() -> bool:
    try:
        return len(os.listdir("/proc/self/task")) == 1
    except OSError:
        return False


_warm: set[str] = set()


def warm_builtins(methods: Iterable[str], tracks: Iterable[str] = ()) -> None:
    """Load the kernels of the built-in ``methods`` and the ``tracks`` here, once (a cold compile is
    announced); only assocbench's code runs here."""
    for name in sorted(set(tracks)):
        warm_track(get_track(name))
    from ..associators.registry import BUILTINS
    from ..kernels import warm
    from .runner import warm_scoring, warm_up

    names = sorted({m.lower() for m in methods} & set(BUILTINS) - _warm)
    # the scoring of associations against truth: every worker of a track whose frames are Problems
    # uses it (no tracks named: assume one does); a track with its own frame loop scores its own way
    scores = not tracks or any(not has(get_track(name), OwnFrames) for name in tracks)
    scoring = [warm_scoring] if scores and "scoring" not in _warm else []
    warm([partial(warm_up, BUILTINS[name]()) for name in names] + scoring)
    _warm.update(names + (["scoring"] if scores else []))


def warm_track(track) -> None:
    """``track.warm_up()`` here, once, so a forkserver's worker of another track than the server
    warmed does not compile inside its timed frames."""
    if f"track {track.name}" not in _warm:
        if has(track, WarmUp):
            track.warm_up()
        _warm.add(f"track {track.name}")


class _Call(NamedTuple):
    """The call a worker is in: run and method indices, frame, limit (s), whose code (``METHOD`` or
    ``TRACK``), start time."""

    run: int
    method: int
    frame: int
    limit: float
    whose: str
    started: float


@dataclass
class _Running:
    task: Task
    progress: _Progress
    process: mp.Process
    conn: object
    call: _Call | None = None   # the call in flight
    heard: bool = False          # any message yet (a worker that dies silently never started)


def _why(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"was killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"was killed by signal {-exitcode}"
    return f"exited with code {exitcode}"


def _stderr(line: str) -> None:
    print(f"assocbench: {line}", file=sys.stderr, flush=True)


class Supervisor:
    """Runs tasks in at most ``slots`` workers at once and enforces each call's limit.
    ``report(line)`` hears, once per method and run, that frames failed because a worker died or
    overran. ``watch(event, k)`` hears each worker ``start``, each ``call`` (frame k), each
    ``frame`` finished and, at least every ``WATCH_TICK_S``, ``tick``."""

    def __init__(self, slots: int = 1, report: Callable[[str], None] = _stderr,
                 watch: Callable[[str, int], None] | None = None) -> None:
        self.slots = max(1, int(slots))
        self.report = report
        self.watch = watch or (lambda event, k: None)
        self.tick = WATCH_TICK_S if watch is not None else None

    def run(self, tasks: Iterable[Task], on_done: Callable[[Task, dict, dict], None]) -> None:
        """Run ``tasks``; ``on_done(task, records, imports)`` as each finishes,
        ``records[(run, method)]`` the per-frame records in order (a ``RecordSpool``, open during
        ``on_done``) and ``imports[(run, method)]`` its worker's import report. Raises
        ``TaskFailed`` at the end if a task failed outside any method call, ``UserError`` at once
        for bad input."""
        pending, live, failed = deque(tasks), [], []
        total = len(pending)
        try:
            while pending or live:
                while pending and len(live) < self.slots:
                    task = pending.popleft()
                    live.append(self._launch(task, _Progress()))
                    self.watch("start", 0)
                wait([w.conn for w in live] + [w.process.sentinel for w in live], _timeout(live, self.tick))
                self.watch("tick", 0)
                for w in list(live):
                    outcome = self._step(w)
                    if outcome is None:
                        continue
                    live.remove(w)
                    if outcome == "done":
                        on_done(w.task, dict(w.progress.records), dict(w.progress.imports))
                        _close_spools(w.progress)
                    elif outcome == "restart":
                        live.append(self._launch(w.task, w.progress))
                    else:
                        failed.append((w.task, outcome))
                        _close_spools(w.progress)
                        self.report(f"{w.task.name} failed: {outcome}")
        finally:
            for w in live:
                _stop(w)
                _close_spools(w.progress)
        if failed:
            task, why = failed[0]
            raise TaskFailed(f"{len(failed)} of {total} task(s) failed; first, {task.name}: {why.splitlines()[0]}")

    def run_one(self, task: Task) -> dict:
        """Records of one task (see ``run``), each (run, method)'s as a list in frame order."""
        out = {}
        self.run([task], lambda _, records, __: out.update({key: list(spool) for key, spool in records.items()}))
        return out

    def run_one_table(self, task: Task, drop: tuple[str, ...] = ()) -> dict:
        """The per-frame table of each (run, method) of one task, from its spooled records."""
        out = {}
        self.run([task], lambda _, records, __: out.update({key: frame_table(spool, drop)
                                                         for key, spool in records.items()}))
        return out

    def _launch(self, task: Task, progress: _Progress) -> _Running:
        if getattr(mp.current_process(), "_inheriting", False):  # a forkserver importing a script
            raise RuntimeError(f"assocbench was run while a process imported the main script; {_GUARD}")
        ctx = _context((m[1] for m in task.methods), {spec.track for _, spec in task.runs})
        here, there = ctx.Pipe(duplex=False)
        done = progress.records.get(progress.resume[:2])   # a closed loop replays these frames
        replay = {k: (rec.get("association"), rec["error"]) for k, rec in (done.items() if done else ())
                  if k < progress.resume[2]}
        process = ctx.Process(target=_worker, name=f"assocbench {task.name}",
                              args=(there, task, progress.resume, progress.faults, dict(os.environ), replay))
        try:
            with _allow_children():
                process.start()
        except (OSError, EOFError) as exc:
            raise RuntimeError(f"cannot start a worker process ({exc}); {_GUARD}") from exc
        finally:
            there.close()  # the worker holds the only writer: its death reads as end of file here
        return _Running(task, progress, process, here)

    def _step(self, w: _Running):
        """Read what ``w`` sent; None while it runs, else ``done``, ``restart`` or why it failed."""
        while True:
            try:
                if not w.conn.poll():
                    break
                msg = w.conn.recv()
            except (EOFError, OSError):
                break
            w.heard = True
            if msg[0] == "call":
                w.call = _Call(*msg[1:], time.monotonic())
                self.watch("call", msg[3])
            elif msg[0] == "frame":
                r, mi, k, record = msg[1:]
                spool = w.progress.records.get((r, mi))
                if spool is None:
                    spool = w.progress.records[(r, mi)] = RecordSpool()
                spool.add(k, record)
                w.call = None
                self.watch("frame", k)
            elif msg[0] == "imports":
                w.progress.imports[(msg[1], msg[2])] = _merged(w.progress.imports.get((msg[1], msg[2])), msg[3])
            elif msg[0] == "done":
                _stop(w, grace=5.0)
                return "done"
            elif msg[0] == "usererror":
                raise UserError(msg[1])
            else:  # crash
                _stop(w)
                return f"{msg[1]}\n{msg[2]}"
        if not w.process.is_alive():
            if w.call is None:
                why = _why(w.process.exitcode)
                _stop(w)
                return (f"its worker process {why} outside any method call"
                        + ("" if w.heard else " before it started (see the error above)"))
            return self._fault(w, f"WorkerDied: the process running the method {_why(w.process.exitcode)}")
        deadline = _deadline(w)
        if deadline is not None and time.monotonic() > deadline:
            if w.call.whose == TRACK:   # the track's own code hung: nothing of the run can be measured
                _stop(w)
                track = w.task.runs[w.call.run][1].track
                return (f"the {track} track's code building frame {w.call.frame}'s problem of {w.task.runs[w.call.run][0]} "
                        f"ran past {w.call.limit:g} s ({WARM_UP_FACTOR} x time_limit_s): the track hangs, so its run "
                        "cannot be measured")
            what = "associate()" if w.call.frame != WARM_UP else "building and warming up the method"
            return self._fault(w, f"TimeLimit: {what} exceeded the time limit of {w.call.limit:g} s")
        return None

    def _fault(self, w: _Running, error: str) -> str:
        """Record the call in flight as failed, kill the worker, and say where to resume."""
        r, mi, k, started = w.call.run, w.call.method, w.call.frame, w.call.started
        _stop(w)
        elapsed = time.monotonic() - started
        resume_at = w.progress.resume
        first = resume_at[2] if (r, mi) == resume_at[:2] else 0
        faults = w.progress.faults.setdefault((r, mi), {})
        if not faults:  # once per method and run: the records name every frame
            where = "while starting, so on every frame" if k == WARM_UP else f"on frame {k}"
            self.report(f"{w.task.methods[mi][0]} failed {where} of {w.task.runs[r][0]} (the run goes on): {error}")
        faults[k] = (error, elapsed)
        w.progress.resume = (r, mi, first if k == WARM_UP else k)
        return "restart"


def _merged(before: dict | None, report: dict) -> dict:
    """One method's import report merged with a killed earlier worker's: every name asked for, each
    module's earliest load."""
    if before is None:
        return report
    loaded = dict(report["loaded"])
    for path, at in before["loaded"].items():
        loaded[path] = min(at, loaded.get(path, at))
    return {**report, "names": sorted(set(report["names"]) | set(before["names"])), "loaded": loaded,
            "earliest": min(report["earliest"], before["earliest"]),
            "libraries": sorted(set(report["libraries"]) | set(before["libraries"]))}


def _deadline(w: _Running) -> float | None:
    """When the call in flight overruns (monotonic clock); None when none is, or no limit."""
    if w.call is None or not math.isfinite(w.call.limit):
        return None
    return w.call.started + w.call.limit


def _timeout(live: list[_Running], tick: float | None = None) -> float | None:
    """Seconds to wait for a worker: until the first deadline, at most ``tick`` (None: no bound)."""
    waits = [max(0.0, d - time.monotonic()) for d in map(_deadline, live) if d is not None]
    waits += [tick] if tick is not None else []
    return min(waits) if waits else None


def _close_spools(progress: _Progress) -> None:
    """Release a finished or failed task's spooled records (their files are anonymous)."""
    for spool in progress.records.values():
        spool.close()
    progress.records.clear()


def _stop(w: _Running, grace: float = 0.0) -> None:
    """End ``w``'s process (killed after ``grace`` s) and its method's, releasing its handles; the
    group dies before ``join`` (an unreaped id is not reused)."""
    if grace:
        wait([w.process.sentinel], grace)
    _kill_session(w.process.pid)
    if w.process.is_alive():
        w.process.kill()
    w.process.join()
    w.conn.close()
    w.process.close()


class _allow_children:
    """Start a worker from a daemonic process too (a dask worker): it is ours to kill and exits with
    its parent."""

    def __enter__(self):
        self.proc = mp.current_process()
        self.daemon = self.proc._config.get("daemon", False)
        self.proc._config["daemon"] = False

    def __exit__(self, *exc):
        self.proc._config["daemon"] = self.daemon


def execute(spec: RunSpec, cache_dir: Path | None = None, associations: bool = False,
            artifacts: Path | None = None, progress: bool = False) -> tuple[pd.DataFrame, dict]:
    """Run ``spec`` in a worker (``time_limit_s`` per call): per-frame records and the summary.
    ``associations=True`` adds an ``association`` column; ``artifacts``: a folder for ``RunFiles``;
    ``progress``: a bar on stderr."""
    name = f"{spec.source.name} seed {spec.seed}"
    task = Task(name, ((name, spec),), ((spec.method, spec.method, dict(spec.params)),),
                str(cache_dir) if cache_dir else None, str(artifacts) if artifacts else None)
    bar = RunProgress(spec.method, len(spec.source)) if progress else None
    try:
        supervisor = Supervisor(1, watch=bar.watch if bar else None)
        frames = supervisor.run_one_table(task, () if associations else ("association",))[(0, 0)]
    finally:
        if bar is not None:
            bar.close()
    return frames, summarize_run(spec.track_impl, frames)
