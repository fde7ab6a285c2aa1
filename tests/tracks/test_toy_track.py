"""A track registered from outside the package (``toy_track.py`` beside this file, loaded by
``ASSOCBENCH_TRACKS``) runs through the one harness: ``run``, ``leaderboard --jobs 2`` with
resume after Ctrl-C, and ``check`` against its own baseline; the package is not touched."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

# imported at collection, before conftest points the cache at a private folder: the subprocesses
# then share the user's compiled kernels (NUMBA_CACHE_DIR) instead of compiling them again
import assocbench  # noqa: F401

HERE = Path(__file__).resolve().parent
SCENE = '<mujoco><worldbody><site name="toy0" pos="0 0 0"/><site name="toy1" pos="1 0 0"/></worldbody></mujoco>\n'
SUITE = """base: {{frames: 4, toy: {{landmarks: 12}}}}
scenes: [{scene}]
difficulties:
  easy: {{belief: {{sigma_position: 0.05}}}}
  hard: {{belief: {{sigma_position: 0.3, clutter: 8}}}}
methods: [mnn, jcbb]
seeds: [0, 1]
"""


@pytest.fixture
def toy(tmp_path) -> tuple[Path, Path]:
    """A toy scene (``toy*`` sites) and a suite over it, written into ``tmp_path``."""
    scene = tmp_path / "toy.xml"
    scene.write_text(SCENE)
    suite = tmp_path / "toy_suite.yaml"
    suite.write_text(SUITE.format(scene=scene))
    return scene, suite


def env(**extra) -> dict:
    """The environment of a user whose track module is on PYTHONPATH and named in ASSOCBENCH_TRACKS."""
    path = os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path, "ASSOCBENCH_TRACKS": "toy_track", **extra}


def cli(*args: str, **extra) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "assocbench.cli.main", *args], env=env(**extra),
                          capture_output=True, text=True, timeout=300, check=False)


def _default_sigint() -> None:
    """In the child before exec: SIGINT to its default (a test started in the background of a
    shell without job control inherits it ignored; see test_faults_plugins)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for(predicate, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not predicate():
        time.sleep(0.1)
    return predicate()


def _manifests(out: Path) -> dict[str, tuple[int, bytes]]:
    """Stored runs under ``out``: manifest name -> (seed, its bytes)."""
    return {p.name: (int(json.loads(p.read_bytes())["run"].rpartition(" seed ")[2]), p.read_bytes())
            for p in out.glob("runs/*.manifest.json")}


def _without_timing(path: Path) -> pd.DataFrame:
    table = pd.read_csv(path)
    return table[[c for c in table.columns if "runtime" not in c]]


def test_run_on_a_user_track(toy):
    scene, _ = toy
    out = scene.parent / "run"
    done = cli("run", "--method", "jcbb", "--scene", str(scene), "--frames", "5", "--out", str(out),
               "--format", "csv")
    assert done.returncode == 0, done.stderr
    summary = pd.read_csv(out / "summary.csv").iloc[0]
    assert summary["frames"] == 5 and summary["status"] == "ok"
    assert summary["precision"] > 0.9 and summary["recall"] > 0.5


WARM_SCRIPT = """
import os, sys, threading
from assocbench.cli.main import main

if __name__ == "__main__":
    threading.Thread(target=threading.Event().wait, daemon=True).start()   # a thread: workers come from a forkserver
    print("parent", os.getpid())
    for k in range(2):   # two runs: two workers forked from the one server
        code = main(["run", "--method", "mnn", "--scene", sys.argv[1], "--frames", "3", "--out", f"{sys.argv[2]}{k}"])
        if code:
            sys.exit(code)
"""


def test_the_forkserver_warms_the_track_once_for_all_its_workers(toy, tmp_path):
    """The forkserver warms the first task's track: its workers inherit the loaded kernels. It used
    to warm only the built-in associators, so each worker warmed its track itself (the dense track:
    0.5 s a worker, 2.8 ms a frame of a 200-frame run); before that, none did and the dense track
    compiled inside its timed frames (a first run's fps 9.4 against 29.7)."""
    scene, _ = toy
    script, log = tmp_path / "start.py", tmp_path / "warmed.txt"
    script.write_text(WARM_SCRIPT)
    done = subprocess.run([sys.executable, str(script), str(scene), str(tmp_path / "run")], env=env(TOY_WARM_LOG=str(log)),
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    parent = int(done.stdout.split("parent")[1].split()[0])
    warmed = [int(pid) for pid in log.read_text().split()] if log.exists() else []
    assert len(warmed) == 1 and warmed[0] != parent, (parent, warmed)   # once, by the server, for both workers


@pytest.mark.slow   # a sweep's Ctrl-C and resume: test_faults_plugins (ctrl-c) and test_harness, by default
def test_an_interrupted_leaderboard_resumes_to_the_same_table(toy, tmp_path):
    """Seed 1's runs are slow (TOY_DELAY_S): Ctrl-C after seed 0's four runs are stored stops the
    sweep; the rerun computes seed 1 only and writes what an uninterrupted sweep writes."""
    scene, suite = toy
    out, log = tmp_path / "out", tmp_path / "built.txt"
    with (tmp_path / "stderr.txt").open("w") as stderr:
        proc = subprocess.Popen([sys.executable, "-m", "assocbench.cli.main", "leaderboard", "--suite", str(suite),
                                 "--out", str(out), "--jobs", "2", "--quiet"], env=env(TOY_DELAY_S="60", TOY_LOG=str(log)),
                                start_new_session=True, stdout=subprocess.DEVNULL, stderr=stderr,
                                preexec_fn=_default_sigint)  # noqa: PLW1509 - the test has no threads
    try:
        assert _wait_for(lambda: len(_manifests(out)) == 4 or proc.poll() is not None, 120)
        assert proc.poll() is None, (tmp_path / "stderr.txt").read_text()
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=15) == 130
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert "finished runs are kept" in (tmp_path / "stderr.txt").read_text()
    kept = _manifests(out)
    assert [seed for seed, _ in kept.values()] == [0] * 4
    log.unlink()
    resumed = cli("leaderboard", "--suite", str(suite), "--out", str(out), "--jobs", "2", "--quiet", TOY_LOG=str(log))
    assert resumed.returncode == 0, resumed.stderr
    assert log.read_text().split() == ["1", "1"]            # seed 1's runs only, both difficulties
    after = _manifests(out)
    assert all(after[name] == kept[name] for name in kept) and len(after) == 8   # seed 0's runs untouched
    fresh = cli("leaderboard", "--suite", str(suite), "--out", str(tmp_path / "fresh"), "--jobs", "2", "--quiet")
    assert fresh.returncode == 0, fresh.stderr
    pd.testing.assert_frame_equal(_without_timing(out / "leaderboard.csv"),
                                  _without_timing(tmp_path / "fresh" / "leaderboard.csv"))
    # scenarios by the scene's short name, never its path
    assert set(pd.read_csv(out / "leaderboard.csv")["scenario"]) == {"toy/easy", "toy/hard"}


def test_check_guards_a_user_track(toy, tmp_path):
    _, suite = toy
    baseline = tmp_path / "baseline.csv"
    update = cli("check", "--suite", str(suite), "--baseline", str(baseline), "--update", "--quiet")
    assert update.returncode == 0, update.stderr
    passed = cli("check", "--suite", str(suite), "--baseline", str(baseline), "--quiet")
    assert passed.returncode == 0, passed.stdout + passed.stderr
    table = pd.read_csv(baseline)
    metrics = table[["precision", "recall"]]
    row, metric = metrics.stack().idxmin()           # the weakest number: raising it is a regression
    assert table.loc[row, metric] < 0.9, table        # else the suite cannot show a regression
    table.loc[row, metric] = 1.0
    table.to_csv(baseline, index=False)
    failed = cli("check", "--suite", str(suite), "--baseline", str(baseline), "--quiet")
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "regressed" in failed.stdout and metric in failed.stdout


@pytest.fixture
def toy_module(tmp_path, monkeypatch):
    """A copy of the toy track's module in ``tmp_path``, named in ASSOCBENCH_TRACKS; unregistered after."""
    from assocbench.tracks import registry as base

    (tmp_path / "toy_copy.py").write_text((HERE / "toy_track.py").read_text())
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("ASSOCBENCH_TRACKS", "toy_copy")
    yield tmp_path / "toy_copy.py"
    base._TRACKS.pop("toy", None)
    sys.modules.pop("toy_copy", None)


def test_a_track_module_named_in_the_environment_registers(toy_module, toy):
    from assocbench.tracks.inference import track_for_scene
    from assocbench.tracks.registry import get_track

    assert get_track("toy").summary and track_for_scene(toy[0]).name == "toy"


def test_a_track_module_that_does_not_import_is_one_line(monkeypatch):
    from assocbench.errors import UserError
    from assocbench.tracks.registry import iter_tracks

    monkeypatch.setenv("ASSOCBENCH_TRACKS", "camera_and_more, no_such_track_module")
    with pytest.raises(UserError, match=r"^track module 'camera_and_more' named in ASSOCBENCH_TRACKS failed "
                                        r"to import: ModuleNotFoundError.*PYTHONPATH\?\)$"):
        list(iter_tracks())


def test_editing_a_user_track_makes_its_stored_runs_out_of_date(toy_module, toy, tmp_path):
    """A stored run made by a user track's old code is not reused after the track is edited."""
    from assocbench.harness.runstore import lookup
    from assocbench.harness.suite import load_suite
    from assocbench.harness.sweep import run_suite

    suite = load_suite(toy[1])
    run_suite(suite, tmp_path / "out", progress=False)
    stored, why = lookup(tmp_path / "out", suite.runs[0])
    assert stored is not None and why is None
    toy_module.write_text(toy_module.read_text() + "\n# edited\n")
    assert lookup(tmp_path / "out", suite.runs[0]) == (None, f"{toy_module} changed")
