"""A stored run is reused only while every input it had is the same: its settings, its scene's
files (meshes and textures in the ``<compiler>`` folders too), the source files its worker
imported (a plugin's helper in another folder), the libraries that change numbers; and a run whose
code was saved while it ran is not stored under the new files' digests (issue 42)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
import uuid
from pathlib import Path

import pandas as pd
import pytest

from assocbench.harness.suite import load_suite
from assocbench.harness.sweep import run_suite

COLUMNS = ["scenario", "method", "seed", "precision", "recall", "f1", "perfect"]


def _suite(tmp_path: Path, methods: str, name: str = "suite.yaml", seeds: str = "[0]", scenes: str = "[checkerboard]",
           frames: int = 2) -> Path:
    path = tmp_path / name
    path.write_text(f"base: {{frames: {frames}}}\nscenes: {scenes}\nmethods: {methods}\nseeds: {seeds}\n")
    return path


def _manifests(out: Path) -> dict[str, dict]:
    return {p.name: json.loads(p.read_text()) for p in (out / "runs").glob("*.manifest.json")}


PLUGIN = '''
from assocbench import Associator, make_associator
from {helper} import PAIR

class Picky(Associator):
    def associate(self, problem):
        return make_associator("mnn").associate(problem) if PAIR else self.empty(problem)
'''


@pytest.mark.parametrize("layout", ["package", "single module", "helper in another folder"])
def test_editing_a_plugins_helper_module_recomputes_its_runs(layout, tmp_path, monkeypatch):
    """The helper a plugin imports, wherever it lives on the path (the issue's case: another folder
    on PYTHONPATH, which reused the old run: recall 0.97 where a fresh run gives 0.5)."""
    name = f"keys_{layout.split()[0]}_{uuid.uuid4().hex[:6]}"
    plugins, helpers = tmp_path / "plugins", tmp_path / ("helpers" if layout == "helper in another folder" else "plugins")
    plugins.mkdir()
    helpers.mkdir(exist_ok=True)
    if layout == "package":
        (plugins / name).mkdir()
        (plugins / name / "__init__.py").write_text("")
        (plugins / name / "method.py").write_text(PLUGIN.format(helper=f"{name}.helper"))
        helper, spec = plugins / name / "helper.py", f"{name}.method:Picky"
    else:
        (plugins / f"{name}.py").write_text(PLUGIN.format(helper=f"{name}_helper"))
        helper, spec = helpers / f"{name}_helper.py", f"{name}:Picky"
    helper.write_text("PAIR = True\n")
    monkeypatch.syspath_prepend(str(helpers))
    monkeypatch.syspath_prepend(str(plugins))
    suite = _suite(tmp_path, f"[{{name: mine, method: '{spec}'}}]")
    before, _ = run_suite(load_suite(suite), tmp_path / "runs", progress=False)
    assert before.loc[0, "recall"] > 0
    helper.write_text("PAIR = False   # edited\n")
    for mod in [m for m in sys.modules if m.startswith(name)]:
        sys.modules.pop(mod)
    after, _ = run_suite(load_suite(suite), tmp_path / "runs", progress=False)
    assert after.loc[0, "recall"] == 0


EDITS_ITSELF = '''
import os, time
from pathlib import Path
from assocbench import Associator, make_associator

class Flips(Associator):
    """Pairs like MNN while its helper says PAIR; the first real frame anywhere rewrites the helper
    to PAIR = False, as a user saving an edit while the sweep runs (this worker has read it)."""
    def associate(self, problem):
        from {helper} import PAIR
        if problem.volume != 100.0 and not os.path.exists(os.environ["KEYS_TOKEN"]):
            Path(os.environ["KEYS_TOKEN"]).write_text("")
            time.sleep(0.1)   # the edit is saved later than the module was loaded, as a user's is
            Path(os.environ["KEYS_HELPER"]).write_text("PAIR = False\\n")
        return make_associator("mnn").associate(problem) if PAIR else self.empty(problem)
'''


def test_a_plugin_edited_while_a_sweep_runs_is_not_stored_under_the_new_code(tmp_path, monkeypatch, capsys):
    """The issue's case: a sweep edited mid-way (seed 0's run made with the old helper, seed 1's
    with the new one), then reverted: the next sweep must give what a fresh one gives. The old
    key, taken before the runs, stored seed 1's new-code numbers under the old code's key."""
    name = f"keys_flips_{uuid.uuid4().hex[:6]}"
    (tmp_path / f"{name}.py").write_text(EDITS_ITSELF.format(helper=f"{name}_helper"))
    helper = tmp_path / f"{name}_helper.py"
    helper.write_text("PAIR = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("KEYS_TOKEN", str(tmp_path / "edited"))
    monkeypatch.setenv("KEYS_HELPER", str(helper))
    suite = _suite(tmp_path, f"[{{name: flips, method: '{name}:Flips'}}]", seeds="[0, 1]")
    during, _ = run_suite(load_suite(suite), tmp_path / "out", progress=False)
    assert during["recall"].tolist()[0] > 0 and during["recall"].tolist()[1] == 0   # old code, then new
    assert "flips on checkerboard/default seed 0 is not stored" in capsys.readouterr().err
    helper.write_text("PAIR = True\n")   # reverted
    (tmp_path / "edited").write_text("")   # no more edits
    sys.modules.pop(f"{name}_helper", None)
    again, _ = run_suite(load_suite(suite), tmp_path / "out", progress=False)
    fresh, _ = run_suite(load_suite(suite), tmp_path / "fresh", progress=False)
    pd.testing.assert_frame_equal(again[COLUMNS], fresh[COLUMNS])
    assert (fresh["recall"] > 0).all()


def _box(half: float) -> str:
    """An OBJ box, ``half`` either side of its origin in x, 0 to 0.6 m in y, 1 m high."""
    v = [(x, y, z) for x in (-half, half) for y in (0, 0.6) for z in (0, 1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    return "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in faces)


def test_a_mesh_edited_under_meshdir_is_simulated_again_and_recomputed(tmp_path, monkeypatch):
    """The issue's case: a planar scene with <compiler meshdir="assets"/> and a rock mesh beside a
    post; the rock grown in place hides the post from the path's start (fewer measurements). Both
    the sequence cache and the stored runs reused the old scans."""
    from user_room import path_csv, room_mjcf

    scene = room_mjcf(tmp_path, "planar")
    text = scene.read_text().replace("<mujoco>", '<mujoco><compiler meshdir="assets"/>'
                                                 '<asset><mesh name="rock" file="rock.obj"/></asset>')
    scene.write_text(text.replace("</worldbody>", '<geom name="rock" type="mesh" mesh="rock" pos="6.0 0.05 0"/>'
                                                  "</worldbody>"))
    (tmp_path / "assets").mkdir()
    rock = tmp_path / "assets" / "rock.obj"
    rock.write_text(_box(0.05))
    suite = tmp_path / "suite.yaml"
    suite.write_text(f"base: {{frames: 6, trajectory: waypoints, trajectory_params: {{file: {path_csv(tmp_path)}}}}}\n"
                     f"scenes: [{scene}]\nmethods: [mnn]\nseeds: [0]\n")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(tmp_path / "cache"))
    _, small = run_suite(load_suite(suite), tmp_path / "out", progress=False)
    rock.write_text(_box(0.3))
    _, grown = run_suite(load_suite(suite), tmp_path / "out", progress=False)
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(tmp_path / "fresh-cache"))
    _, fresh = run_suite(load_suite(suite), tmp_path / "fresh", progress=False)
    assert grown["m"].sum() == fresh["m"].sum() < small["m"].sum()


def test_a_planar_runs_inputs_are_its_own_track_and_no_other(tmp_path):
    """A planar run's record names the planar track's modules and none of another track's: a
    docstring edit in tracks/dense/plots.py reuses it."""
    out = tmp_path / "out"
    run_suite(load_suite(_suite(tmp_path, "[mnn]", scenes="[park]")), out, progress=False)
    (manifest,) = _manifests(out).values()
    files = manifest["inputs"]["files"]
    assert "assocbench/tracks/planar/track.py" in files and "assocbench/associators/mnn.py" in files
    assert "assocbench/harness/runner.py" in files
    others = [f for f in files if f.startswith(("assocbench/tracks/dense/", "assocbench/tracks/camera/",
                                                "assocbench/tracks/lines/"))]
    assert others == [] and "numpy" in manifest["inputs"]["libraries"]


def test_a_modules_data_files_are_among_the_inputs_of_the_runs_that_import_it():
    """The learned models (``*.json`` beside their module) are inputs of a run that imports the
    learned associator: a retrained model recomputes its runs."""
    from assocbench.harness.inputs import ImportGraph, run_inputs

    report = {"names": [], "loaded": {}, "earliest": time.time(), "libraries": []}   # loaded now
    files = run_inputs(ImportGraph(), {"assocbench.associators.learned.associator"}, report).files
    assert {"assocbench/associators/learned/planar.json", "assocbench/associators/learned/camera.json"} <= set(files)


SPY = '''
import os, sys
from assocbench import Associator, make_associator

class Spy(Associator):
    def associate(self, problem):
        with open(os.environ["SPY_OUT"], "w") as fh:
            fh.write("\\n".join(sorted(sys.modules)))
        return make_associator("mnn").associate(problem)
'''


# a thread in the command's process: its workers come from a forkserver, which has imported only
# assocbench, so a worker's modules are those it imported itself (a forked worker inherits the
# command's, and the command asks every track whether it owns the method)
THREADED_CLI = ("import sys, threading; threading.Thread(target=threading.Event().wait, daemon=True).start(); "
                "from assocbench.cli.main import main; sys.exit(main(sys.argv[1:]))")


def test_a_planar_worker_imports_no_module_of_another_track(tmp_path):
    """The registry stays lazy: the worker of a planar run never imports the dense, camera or
    lines track's modules, so they cannot be among its inputs."""
    (tmp_path / "keys_spy.py").write_text(SPY)
    suite = tmp_path / "suite.yaml"
    suite.write_text("track: planar\nbase: {frames: 2}\nscenes: [park]\nmethods: [{name: spy, method: 'keys_spy:Spy'}]\n"
                     "seeds: [0]\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")])),
           "SPY_OUT": str(tmp_path / "modules.txt")}
    done = subprocess.run([sys.executable, "-c", THREADED_CLI, "leaderboard", "--suite", str(suite), "--out",
                           str(tmp_path / "out"), "--quiet"], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    modules = (tmp_path / "modules.txt").read_text().split()
    assert "assocbench.tracks.planar.track" in modules
    assert [m for m in modules if m.startswith(("assocbench.tracks.dense", "assocbench.tracks.camera",
                                                "assocbench.tracks.lines"))] == []


def _count_computed(monkeypatch) -> list[str]:
    """The labels of the runs each sweep computes from now on (the others are reused)."""
    import assocbench.harness.sweep as sweep

    computed = []
    real = sweep.run_cell
    monkeypatch.setattr(sweep, "run_cell", lambda runs, cache_dir=None, graph=None: (
        computed.extend(r.entry.label for r in runs), real(runs, cache_dir, graph))[1])
    return computed


def test_a_method_costs_only_its_own_runs(tmp_path, monkeypatch):
    """Adding a method computes its runs alone, removing one computes nothing, changing one
    method's parameters recomputes that method; the other rows are the stored ones."""
    computed = _count_computed(monkeypatch)
    out, seeds = tmp_path / "out", "[0, 1]"
    two, _ = run_suite(load_suite(_suite(tmp_path, "[enn, mnn]", seeds=seeds)), out, progress=False)
    assert sorted(computed) == ["enn", "enn", "mnn", "mnn"]
    computed.clear()
    three, _ = run_suite(load_suite(_suite(tmp_path, "[enn, mnn, lsa]", seeds=seeds)), out, progress=False)
    assert computed == ["lsa", "lsa"]
    pd.testing.assert_frame_equal(three[three["method"] != "lsa"][COLUMNS].reset_index(drop=True), two[COLUMNS])
    computed.clear()
    run_suite(load_suite(_suite(tmp_path, "[mnn]", seeds=seeds)), out, progress=False)
    assert computed == []
    tuned = textwrap.dedent("""[enn, mnn, {name: lsa, method: lsa, params: {confidence: 0.9}}]""")
    run_suite(load_suite(_suite(tmp_path, tuned, seeds=seeds)), out, progress=False)
    assert computed == ["lsa", "lsa"]


def test_editing_one_built_in_method_recomputes_only_its_runs(tmp_path, monkeypatch):
    """Each built-in associator is imported when asked for, so a run's inputs are its own method's
    modules and none of another's: an edit in mnn.py recomputes MNN's runs alone, one in lsa.py
    JCBB's alone (jcbb.py imports it). The registry imported every built-in, so any such edit
    recomputed every method's runs. An edit is what the stored digest sees: the file's digest
    changes (the package's files are never written by a test)."""
    import assocbench.harness.inputs as inputs

    computed = _count_computed(monkeypatch)
    out, suite = tmp_path / "out", _suite(tmp_path, "[mnn, jcbb]")
    first, _ = run_suite(load_suite(suite), out, progress=False)
    files = {m["run"].split()[0]: set(m["inputs"]["files"]) for m in _manifests(out).values()}
    mine = "assocbench/associators/"
    assert sorted(f for f in files["mnn"] - files["jcbb"] if f.startswith(mine)) == [f"{mine}mnn.py"]
    assert {f"{mine}jcbb.py", f"{mine}lsa.py", f"{mine}rjc.py"} <= files["jcbb"] - files["mnn"]
    assert not any(f.startswith((f"{mine}dense/", f"{mine}learned/", f"{mine}snn.py")) for f in files["mnn"] | files["jcbb"])
    edited, real = set(), inputs.file_digest

    def digest(path: Path) -> tuple[str, int] | None:
        got = real(path)
        return (f"edited {got[0]}", got[1]) if got is not None and inputs.file_name(path) in edited else got

    monkeypatch.setattr(inputs, "file_digest", digest)
    for name, runs_of in (("mnn.py", ["mnn"]), ("lsa.py", ["jcbb"]), ("snn.py", [])):
        edited.add(mine + name)
        computed.clear()
        again, _ = run_suite(load_suite(suite), out, progress=False)
        assert computed == runs_of, name
        pd.testing.assert_frame_equal(again[COLUMNS], first[COLUMNS])   # the same code: the same numbers


def test_side_by_side_tasks_make_different_sequences(tmp_path):
    """The missing runs form a task per scene, seed and difficulty, taken a sequence at a time in
    turn: with --jobs 2 on a cold cache, two difficulties of one scene rendered it twice at once."""
    from assocbench.harness.sweep import missing_cells

    path = tmp_path / "suite.yaml"
    path.write_text("base: {frames: 2}\nscenes: [checkerboard, room]\nmethods: [enn, mnn]\nseeds: [0]\n"
                    "difficulties: {easy: {}, hard: {belief: {clutter: 5}}}\n")
    done, tasks, changed = missing_cells(load_suite(path), tmp_path / "out")
    assert done == {} and changed == []
    assert [(runs[0].cell.scenario, [r.entry.label for r in runs]) for runs in tasks] == [
        ("checkerboard/easy", ["enn", "mnn"]), ("room/easy", ["enn", "mnn"]),
        ("checkerboard/hard", ["enn", "mnn"]), ("room/hard", ["enn", "mnn"])]


def test_an_installed_plugins_own_modules_are_hashed_where_other_libraries_are_not(tmp_path, monkeypatch):
    """A plugin installed with pip lives among the libraries, whose modules are not hashed (their
    versions are recorded where they change numbers): its own package's modules are its code."""
    import assocbench.harness.inputs as inputs

    site = tmp_path / "site"
    (site / "keys_installed").mkdir(parents=True)
    (site / "keys_installed" / "__init__.py").write_text("")
    (site / "keys_installed" / "method.py").write_text("from .helper import K\nimport keys_other_lib\n")
    (site / "keys_installed" / "helper.py").write_text("K = 1\n")
    (site / "keys_other_lib.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setattr(inputs, "is_library", lambda path: path.is_relative_to(site))
    report = {"names": [], "loaded": {}, "earliest": 0.0, "libraries": []}
    files = inputs.run_inputs(inputs.ImportGraph(), {"keys_installed.method"}, report, {"keys_installed"}).files
    assert {Path(f).name for f in files} == {"__init__.py", "method.py", "helper.py"}
    assert inputs.run_inputs(inputs.ImportGraph(), {"keys_installed.method"}, report).files == {}
