"""Fault injection: methods that die, exit, hang or edit their problem, and sweeps that are
interrupted or killed. Each is isolated: the frame (or the method) fails, named, and the rest of
the run or sweep completes and is kept."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from assocbench.harness.suite import load_suite
from assocbench.harness.sweep import run_suite

HARD = "{sigma_position: 0.10, sigma_rotation: 2.0, sigma_landmark: 0.05, sigma_common: 0.05, clutter: 15}"

# the warm-up call gets a tiny problem of volume 100; the frames' problems are images (volume W*H)
PLUGINS = '''
import ctypes, os, sys, time
import numpy as np
from assocbench import Associator, make_associator

def warming(problem):
    return problem.volume == 100.0

class Exits(Associator):
    def associate(self, problem):
        if not warming(problem):
            os._exit(1)
        return self.empty(problem)

class Segfaults(Associator):
    def associate(self, problem):
        if not warming(problem):
            ctypes.string_at(0)
        return self.empty(problem)

class DiesWarmingUp(Associator):
    def associate(self, problem):
        if warming(problem):
            os._exit(3)
        return self.empty(problem)

class SysExit(Associator):
    def associate(self, problem):
        sys.exit(0)

class SysExitWarmingUp(Associator):
    def associate(self, problem):
        if warming(problem):
            sys.exit(0)
        return make_associator("mnn").associate(problem)

class Hangs(Associator):
    def associate(self, problem):
        if not warming(problem):
            time.sleep(60)
        return self.empty(problem)

class HangsWarmingUp(Associator):
    def associate(self, problem):
        if warming(problem):
            time.sleep(60)
        return self.empty(problem)

class SpawnsAndHangs(Associator):
    """Starts three child processes (an external solver), logs their ids, then hangs."""
    def associate(self, problem):
        if not warming(problem):
            import subprocess
            for _ in range(3):
                child = subprocess.Popen(["sleep", "300"])
                with open(os.environ["CHILD_LOG"], "a") as log:
                    log.write(f"{child.pid}\\n")
            time.sleep(60)
        return self.empty(problem)

class Mutates(Associator):
    """Edits the problem it is given in place, and swaps an array of the frozen dataclass."""
    def associate(self, problem):
        problem.z.flags.writeable = True
        problem.z[:] += 1000.0
        object.__setattr__(problem, "zhat", problem.zhat + 500.0)
        return self.empty(problem)

_fast = None

def stubborn_sleep(seconds):
    """Sleep through interrupts, as native code that never checks for signals does."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            time.sleep(end - time.monotonic())
        except KeyboardInterrupt:
            pass

class OneFastJob(Associator):
    """The first process to call it is fast; every other one hangs, deaf to interrupts (so one
    job finishes and the others would take minutes)."""
    def associate(self, problem):
        global _fast
        if warming(problem):
            return self.empty(problem)
        if _fast is None:
            try:
                os.close(os.open(os.environ["FAST_TOKEN"], os.O_CREAT | os.O_EXCL))
                _fast = True
            except FileExistsError:
                _fast = False
        if not _fast:
            stubborn_sleep(60)
        return self.empty(problem)
'''


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """A module of faulty associators importable here and in worker processes (sys.path is
    handed to workers; PYTHONPATH to subprocesses)."""
    name = f"faults_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}.py").write_text(PLUGINS)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield name
    sys.modules.pop(name, None)


def write_suite(tmp_path, methods: str, seeds="[0]", frames=2, extra="", name="suite.yaml") -> Path:
    path = tmp_path / name
    path.write_text(f"base: {{frames: {frames}{extra}}}\nscenes: [checkerboard]\n"
                    f"difficulties:\n  hard:\n    belief: {HARD}\nmethods: {methods}\nseeds: {seeds}\n")
    return path


def entries(module: str, *classes: str) -> str:
    return ", ".join(f"{{name: {c.lower()}, method: '{module}:{c}'}}" for c in classes)


def cli_env(tmp_path, **extra) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    return {**env, **extra}


def test_dying_methods_fail_their_frames_and_the_sweep_keeps_the_rest(tmp_path, plugins, capsys):
    """os._exit and a segfault inside associate (and an exit during warm-up), under --jobs 2:
    the dying methods fail every frame, named; the healthy method's results are complete.
    (Here the workers come from a forkserver, as numpy's thread pool runs in this process; the
    command-line tests below fork them.)"""
    suite = load_suite(write_suite(tmp_path, f"[mnn, {entries(plugins, 'Exits', 'Segfaults', 'DiesWarmingUp')}]",
                                   seeds="[0, 1]"))
    summaries, _ = run_suite(suite, tmp_path / "runs", jobs=2, progress=False)
    rows = summaries.set_index(["method", "seed"]).sort_index()
    assert len(rows) == 8
    for seed in (0, 1):
        assert rows.loc[("mnn", seed), "failures"] == 0 and rows.loc[("mnn", seed), "recall"] > 0
        assert rows.loc[("exits", seed), "failures"] == 2
        assert "exited with code 1" in rows.loc[("exits", seed), "error"]
        assert rows.loc[("segfaults", seed), "failures"] == 2
        assert "SIGSEGV" in rows.loc[("segfaults", seed), "error"]
        assert rows.loc[("dieswarmingup", seed), "failures"] == 2
        assert "exited with code 3" in rows.loc[("dieswarmingup", seed), "error"]
    err = capsys.readouterr().err
    for label in ("exits", "segfaults", "dieswarmingup"):
        assert sum(line.startswith(f"assocbench: {label} failed") for line in err.splitlines()) == 2  # one per job


def test_run_survives_a_method_that_exits_or_segfaults(tmp_path, plugins):
    """A single-process ``run`` used to exit 1 or 139 with no message: now each frame is a named
    failure, the summary is printed, and the exit status is not the plugin's."""
    script = ("import sys\nfrom assocbench.cli.main import main\n"
              "for cls in ('Exits', 'Segfaults'):\n"
              f"    code = main(['run', '--method', '{plugins}:' + cls, '--scene', 'checkerboard', '--frames', '2',\n"
              f"                 '--out', r'{tmp_path / 'out'}', '--format', 'csv'])\n"
              "    print('exit status', cls, code, flush=True)\n")
    proc = subprocess.run([sys.executable, "-c", script], env=cli_env(tmp_path), capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    for cls, why in (("Exits", "exited with code 1"), ("Segfaults", "killed by SIGSEGV")):
        assert f"exit status {cls} " in proc.stdout
        assert f"{plugins}:{cls} failed on frame 0" in proc.stderr and why in proc.stderr
    assert proc.stdout.count(",2,2,") == 2   # frames 2, failures 2 in each summary line


def test_sys_exit_in_a_method_is_a_failure_not_the_end_of_the_sweep(tmp_path, plugins):
    """sys.exit(0) inside associate fails the frame (it used to end leaderboard, run and check
    with exit 0 and no output); in warm-up it is ignored like any warm-up error."""
    suite = load_suite(write_suite(tmp_path, f"[{entries(plugins, 'SysExit', 'SysExitWarmingUp')}, mnn]"))
    summaries, _ = run_suite(suite, tmp_path / "runs", progress=False)
    rows = summaries.set_index("method")
    assert rows.loc["sysexit", "failures"] == 2 and rows.loc["sysexit", "error"] == "SystemExit: 0"
    assert rows.loc["sysexitwarmingup", "failures"] == 0
    for col in ("precision", "recall"):
        assert rows.loc["sysexitwarmingup", col] == rows.loc["mnn", col]


def test_a_hanging_method_fails_each_call_at_the_time_limit(tmp_path, plugins):
    """time_limit_s bounds every associate() call (ten times that for warm-up): a method that
    sleeps 60 s per call fails each frame after the limit instead of taking a minute per frame."""
    suite = load_suite(write_suite(tmp_path, f"[{entries(plugins, 'Hangs', 'HangsWarmingUp')}]",
                                   extra=", time_limit_s: 0.3"))
    start = time.monotonic()
    summaries, _ = run_suite(suite, tmp_path / "runs", progress=False)
    assert time.monotonic() - start < 40   # the sleeps alone would take 3 minutes
    rows = summaries.set_index("method")
    assert rows.loc["hangs", "failures"] == 2
    assert "associate() exceeded the time limit of 0.3 s" in rows.loc["hangs", "error"]
    assert rows.loc["hangswarmingup", "failures"] == 2
    assert "warming up the method exceeded the time limit of 3 s" in rows.loc["hangswarmingup", "error"]


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_the_children_of_a_method_killed_at_its_time_limit_die_with_it(tmp_path, plugins, monkeypatch):
    """Reproduction: a method that starts child processes (an external solver: here 3 `sleep 300`
    a call) and hangs: at the time limit its worker was killed, but its children lived on,
    reparented to PID 1 (6 `sleep` processes left after 2 frames). The worker's whole session is
    killed now."""
    log = tmp_path / "children.txt"
    monkeypatch.setenv("CHILD_LOG", str(log))
    suite = load_suite(write_suite(tmp_path, f"[{entries(plugins, 'SpawnsAndHangs')}]", extra=", time_limit_s: 1"))
    summaries, _ = run_suite(suite, tmp_path / "runs", progress=False)
    assert summaries.loc[0, "failures"] == 2
    children = [int(pid) for pid in log.read_text().split()]
    assert len(children) == 6
    assert _wait_for(lambda: not any(map(_running, children)), 5), [p for p in children if _running(p)]


def test_a_method_that_edits_its_problem_changes_nobody_elses_numbers(tmp_path, plugins):
    """A method that makes the problem writeable and edits it, or swaps an array of the frozen
    problem, ran first: MNN's numbers are those it gets alone, and the mutating method itself is
    scored against the pristine problem (its empty answer misses every true pair)."""
    alone, _ = run_suite(load_suite(write_suite(tmp_path, "[mnn]", frames=3, name="alone.yaml")),
                         tmp_path / "alone", progress=False)
    after, _ = run_suite(load_suite(write_suite(tmp_path, f"[{entries(plugins, 'Mutates')}, mnn]", frames=3,
                                                name="after.yaml")), tmp_path / "after", progress=False)
    cols = ["precision", "recall", "f1", "perfect", "surprisal_gap", "failures"]
    mnn_after = after[after["method"] == "mnn"][cols].reset_index(drop=True)
    assert mnn_after.equals(alone[cols].reset_index(drop=True))
    assert alone.loc[0, "recall"] > 0
    mutated = after.set_index("method").loc["mutates"]
    assert mutated["failures"] == 0 and mutated["recall"] == 0


def _survivors(marker: str) -> list[int]:
    """Processes whose environment carries ``marker`` (a sweep and everything it started)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if marker.encode() in (entry / "environ").read_bytes():
                    pids.append(int(entry.name))
            except OSError:
                pass
    return pids


def _wait_for(predicate, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.1)
    return predicate()


def _default_sigint() -> None:
    """In the child before exec: SIGINT back to its default. A test run started in the background
    of a shell without job control inherits SIGINT ignored, and Python then never raises
    KeyboardInterrupt, so the child would stand for a user who cannot press Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="reads /proc")
@pytest.mark.parametrize("how", ["ctrl-c", pytest.param("sigterm", marks=pytest.mark.slow),   # Ctrl-C's path, by default
                                 pytest.param("sigkill", marks=pytest.mark.slow)])
def test_a_stopped_sweep_returns_at_once_keeps_finished_jobs_and_leaves_no_process(tmp_path, plugins, how):
    """leaderboard --jobs 2 with one finished job, two hanging ones deaf to interrupts and one
    queued: Ctrl-C (SIGINT to the process group) and SIGTERM return within seconds (not after
    every job ran), the finished job stays stored, and no process of the sweep outlives it;
    after kill -9 its workers exit by themselves."""
    marker = f"ASSOCBENCH_TEST_MARK={uuid.uuid4().hex}"
    suite = write_suite(tmp_path, f"[{entries(plugins, 'OneFastJob')}]", seeds="[0, 1, 2, 3]",
                        extra=", time_limit_s: 120")
    out = tmp_path / "out"
    env = cli_env(tmp_path, FAST_TOKEN=str(tmp_path / "token"), ASSOCBENCH_TEST_MARK=marker.split("=")[1])
    log = tmp_path / "stderr.txt"   # a file, not a pipe: orphans would hold a pipe open
    with log.open("w") as stderr:
        proc = subprocess.Popen([sys.executable, "-m", "assocbench.cli.main", "leaderboard", "--suite", str(suite),
                                 "--out", str(out), "--jobs", "2", "--quiet"], env=env, start_new_session=True,
                                stdout=subprocess.DEVNULL, stderr=stderr, preexec_fn=_default_sigint)
    try:
        assert _wait_for(lambda: list(out.rglob("*.manifest.json")) or proc.poll() is not None, 240)
        assert proc.poll() is None, log.read_text()
        time.sleep(0.5)   # the other jobs are now hanging in their workers
        if how == "ctrl-c":
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGTERM if how == "sigterm" else signal.SIGKILL)
        code = proc.wait(timeout=15)
        err = log.read_text()
        if how != "sigkill":
            assert code == (130 if how == "ctrl-c" else 143), err
            assert "finished runs are kept" in err
        assert _wait_for(lambda: not _survivors(marker), 10), f"left running: {_survivors(marker)}"
        assert len(list(out.rglob("*.manifest.json"))) == 1   # the finished job, kept
    finally:
        for pid in _survivors(marker):
            os.kill(pid, signal.SIGKILL)


def _toy_cli(tmp_path, *args, **env):
    """``assocbench`` with the toy plugin track registered (``ASSOCBENCH_TRACKS``) and ``env`` set."""
    from tests.tracks.test_toy_track import cli

    return cli(*args, "--out", str(tmp_path / "out"), **env)


@pytest.mark.parametrize("claims", ["raise", "all"])
def test_a_plugin_track_that_claims_wrongly_takes_no_shipped_scene(tmp_path, claims):
    """Reproduction: a plugin track whose ``claims_scene()`` raised broke every run, built-in scenes
    included (``assocbench run --scene park`` printed the plugin's traceback); one that claimed every
    scene made ``park`` refused with advice to rename its posts. A shipped scene belongs to the track
    that ships it, asked before any plugin's convention."""
    done = _toy_cli(tmp_path, "run", "--method", "mnn", "--scene", "park", "--frames", "3", TOY_CLAIMS=claims)
    assert done.returncode == 0, done.stderr
    assert "on park (planar track)" in done.stdout


def test_a_plugin_track_that_raises_when_asked_is_named_in_one_line(tmp_path):
    """For a user MJCF the conventions are asked: the plugin that raises is named, with the way out."""
    from tests.tracks.test_toy_track import SCENE

    scene = tmp_path / "mine.xml"
    scene.write_text(SCENE)
    done = _toy_cli(tmp_path, "run", "--method", "mnn", "--scene", str(scene), TOY_CLAIMS="raise")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("assocbench: error: track plugin 'toy'") and "raised in claims_scene" in last
    assert "--track" in last
    named = _toy_cli(tmp_path, "run", "--track", "toy", "--method", "mnn", "--scene", str(scene), "--frames", "2",
                     TOY_CLAIMS="raise")
    assert named.returncode == 0, named.stderr     # a run that names its track asks no convention


def test_a_track_whose_problem_hangs_fails_the_run_in_one_line(tmp_path):
    """Reproduction: a plugin track whose ``problems()`` hung hung ``assocbench run`` silently: the
    time limit covered only ``associate()``. Building a frame's problem is the track's call, limited
    to 10 x ``time_limit_s``; past it the run cannot be measured: exit 1, one line naming the track."""
    from tests.tracks.test_toy_track import SCENE

    scene = tmp_path / "toy.xml"
    scene.write_text(SCENE)
    start = time.monotonic()
    done = _toy_cli(tmp_path, "run", "--method", "mnn", "--scene", str(scene), "--frames", "3",
                    "--set", "time_limit_s=0.3", TOY_HANG="1")
    assert time.monotonic() - start < 60
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "the toy track's code building frame 1's problem" in done.stderr and "ran past 3 s" in done.stderr
