"""The harness: suites, leaderboard files, failure isolation, resume, check against a baseline."""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
import pytest

from assocbench.cli.main import main
from assocbench.harness.suite import load_suite
from assocbench.harness.sweep import run_suite

HARD = "{sigma_position: 0.10, sigma_rotation: 2.0, sigma_landmark: 0.05, sigma_common: 0.05, clutter: 15}"


def write_suite(tmp_path, methods: str, scenes="[checkerboard]", frames=6, name="suite.yaml", difficulty=HARD):
    path = tmp_path / name
    path.write_text(f"base: {{frames: {frames}}}\nscenes: {scenes}\n"
                    f"difficulties:\n  hard:\n    belief: {difficulty}\nmethods: {methods}\nseeds: [0]\n")
    return path


PLUGINS = '''
import numpy as np
from assocbench import Associator, make_associator

class Raises(Associator):
    def associate(self, problem):
        raise RuntimeError("boom")

class Invalid(Associator):
    def associate(self, problem):
        return np.zeros(problem.n, dtype=int)   # feature 0 used by every landmark

class Degraded(Associator):
    """JCBB that forgets every third pairing it makes."""
    def associate(self, problem):
        out = make_associator("jcbb").associate(problem)
        out[::3] = -1
        return out
'''


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    (tmp_path / "bench_plugins.py").write_text(PLUGINS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "bench_plugins", raising=False)   # each test imports its own file
    yield "bench_plugins"
    sys.modules.pop("bench_plugins", None)


def test_leaderboard_discriminates_on_the_hard_scenario(tmp_path, capsys):
    suite = write_suite(tmp_path, "[enn, mnn, jcbb]")
    assert main(["leaderboard", "--suite", str(suite), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    table = pd.read_csv(tmp_path / "out" / "leaderboard.csv").set_index("method")
    assert table.loc["jcbb", "precision"] >= table.loc["mnn", "precision"]
    assert table.loc["jcbb", "precision"] >= table.loc["enn", "precision"]
    assert table.loc["jcbb", "f1"] >= table.loc["mnn", "f1"] >= table.loc["enn", "f1"]
    for name in ("leaderboard.md", "leaderboard_pr.png", "leaderboard_runtime.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    assert "## checkerboard/hard" in (tmp_path / "out" / "leaderboard.md").read_text()


def test_failing_plugins_do_not_stop_the_sweep(tmp_path, plugins):
    suite = load_suite(write_suite(tmp_path, f"[mnn, {{name: raises, method: '{plugins}:Raises'}}, "
                                             f"{{name: invalid, method: '{plugins}:Invalid'}}]", frames=3))
    summaries, _ = run_suite(suite, tmp_path / "runs", progress=False)
    rows = summaries.set_index("method")
    assert rows.loc["raises", "failures"] == 3 and "RuntimeError: boom" in rows.loc["raises", "error"]
    assert rows.loc["invalid", "failures"] == 3 and "more than once" in rows.loc["invalid", "error"]
    assert rows.loc["mnn", "failures"] == 0 and rows.loc["mnn", "recall"] > 0


def test_interrupted_sweep_resumes_without_rerunning_done_runs(tmp_path, monkeypatch):
    import assocbench.harness.sweep as sweep

    suite = load_suite(write_suite(tmp_path, "[enn]", scenes="[checkerboard, room]", frames=2))
    calls = []
    real = sweep.run_cell

    def flaky(runs, cache_dir=None, graph=None):
        calls.append(runs[0].cell.scene)
        if runs[0].cell.scene == "room" and len(calls) == 2:
            raise KeyboardInterrupt
        return real(runs, cache_dir, graph)

    monkeypatch.setattr(sweep, "run_cell", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_suite(suite, tmp_path / "runs", progress=False)
    summaries, _ = run_suite(suite, tmp_path / "runs", progress=False)
    assert calls == ["checkerboard", "room", "room"]
    assert sorted(summaries["scene"]) == ["checkerboard", "room"]


def test_editing_a_plugin_invalidates_its_stored_results(tmp_path, plugins):
    """A stored run records the code that made it: after the plugin's file changes, the same
    suite recomputes instead of reusing the old numbers, and stores the new run in its place."""
    suite_path = write_suite(tmp_path, f"[{{name: mine, method: '{plugins}:Degraded'}}]", frames=2)
    before, _ = run_suite(load_suite(suite_path), tmp_path / "runs", progress=False)
    (tmp_path / "bench_plugins.py").write_text(PLUGINS.replace("out[::3] = -1", "pass  # no longer degraded"))
    sys.modules.pop(plugins, None)
    after, _ = run_suite(load_suite(suite_path), tmp_path / "runs", progress=False)
    assert after.loc[0, "recall"] > before.loc[0, "recall"]
    assert len(list((tmp_path / "runs" / "runs").glob("*.summary.csv"))) == 1


def test_editing_a_waypoint_file_invalidates_its_stored_results(tmp_path):
    """A stored run is keyed by the waypoint file's content, not its name (as by the scene's):
    after the file is edited, the same suite drives the new path instead of reusing old numbers."""
    from user_room import PATH, path_csv, room_mjcf

    scene, file = room_mjcf(tmp_path, "planar"), path_csv(tmp_path)
    suite_path = tmp_path / "suite.yaml"
    suite_path.write_text(f"base: {{frames: 4, trajectory: waypoints, trajectory_params: {{file: {file}}}}}\n"
                          f"scenes: [{scene}]\ndifficulties:\n  easy: {{}}\nmethods: [jcbb]\nseeds: [0]\n")
    run_suite(load_suite(suite_path), tmp_path / "runs", progress=False)
    path_csv(tmp_path, [(7.5, 1.3)] + PATH[1:])
    run_suite(load_suite(suite_path), tmp_path / "runs", progress=False)
    assert len(list((tmp_path / "runs" / "runs").glob("*.summary.csv"))) == 2


def test_rewriting_a_file_a_method_parameter_names_changes_its_stored_runs_key(tmp_path):
    """A learned model retrained in place (same path, new trees) must not reuse stored numbers."""
    import shutil
    from pathlib import Path

    from assocbench.associators.learned.forest import __file__ as forest_file

    model = tmp_path / "model.json"
    shutil.copy(Path(forest_file).parent / "camera.json", model)
    suite = write_suite(tmp_path, f"[{{name: mine, method: learned, params: {{model: '{model}'}}}}]", frames=2)
    before = load_suite(suite).runs[0].key
    assert load_suite(suite).runs[0].key == before
    model.write_text(model.read_text() + "\n")
    assert load_suite(suite).runs[0].key != before


def test_check_passes_against_its_own_baseline_and_catches_a_degraded_plugin(tmp_path, plugins, capsys):
    good = write_suite(tmp_path, "[{name: mine, method: jcbb}]", scenes="[room]", frames=4, name="good.yaml",
                       difficulty="{sigma_position: 0.03, sigma_rotation: 0.5}")
    bad = write_suite(tmp_path, f"[{{name: mine, method: '{plugins}:Degraded'}}]", scenes="[room]", frames=4,
                      name="bad.yaml", difficulty="{sigma_position: 0.03, sigma_rotation: 0.5}")
    baseline = tmp_path / "baseline.csv"
    assert main(["check", "--suite", str(good), "--baseline", str(baseline), "--update", "--quiet"]) == 0
    assert capsys.readouterr().out == f"wrote 1 baseline(s): {baseline}\n"
    assert main(["check", "--suite", str(good), "--baseline", str(baseline)]) == 0
    assert capsys.readouterr().out.startswith(f"ok: 1 scenario × method rows compared with {baseline}, all within")
    assert main(["check", "--suite", str(good), "--baseline", str(baseline), "--quiet"]) == 0
    # off a terminal (capsys) too, --quiet is the one summary line, not the line per suite
    assert capsys.readouterr().out == "ok: 1 scenario × method rows compared in 1 suite(s) (good), all within tolerance\n"
    assert main(["check", "--suite", str(bad), "--baseline", str(baseline), "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "regressed" in out and "recall" in out and "mine" in out
    assert out.startswith("check failed: ") and out.endswith("\ncheck failed: 1 of 1 suite(s) (bad)\n"), out


def test_dask_executor_on_a_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    suite = load_suite(write_suite(tmp_path, "[enn, mnn]", scenes="[checkerboard]", frames=2))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        summaries, _ = run_suite(suite, tmp_path / "dask", executor="dask", address=cluster.scheduler_address,
                                 progress=False)
    local, _ = run_suite(suite, tmp_path / "local", progress=False)
    cols = ["method", "precision", "recall", "f1", "perfect"]
    pd.testing.assert_frame_equal(summaries[cols], local[cols])


def test_parallel_jobs_give_the_same_numbers(tmp_path):
    suite = load_suite(write_suite(tmp_path, "[enn, lsa]", scenes="[checkerboard, room]", frames=2))
    one, _ = run_suite(suite, tmp_path / "one", progress=False)
    two, _ = run_suite(suite, tmp_path / "two", jobs=2, progress=False)
    cols = ["scenario", "method", "precision", "recall", "surprisal_gap"]
    pd.testing.assert_frame_equal(one[cols], two[cols])
    assert np.isfinite(one["surprisal_gap"]).all()
