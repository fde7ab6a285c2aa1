"""The benchmark scripts' ``--help`` states what each one measures in whole sentences: its
description is the module docstring's first paragraph, not its first line (which cut
``dense_rate.py``'s description mid-command, after ``assocbench run --method projective``)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
SCRIPTS = sorted(p for p in BENCHMARKS.glob("*.py") if "ArgumentParser(" in p.read_text())
# running a benchmark script (a child that loads the kernels, some of them render and fit) is the slow
# set's: the scripts measure the package, they are not it; their pure functions are tested by default
script_run = pytest.mark.slow


def first_paragraph(script: Path) -> str:
    """The module docstring's first paragraph, whitespace collapsed as argparse's help reflows it."""
    return " ".join(ast.get_docstring(ast.parse(script.read_text())).split("\n\n")[0].split())


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_description_is_a_whole_paragraph(script):
    """The argument parser is described by something that ends a sentence, not a line cut short."""
    source = script.read_text()
    assert "__doc__.splitlines()[0]" not in source, f"{script.name}: --help would show a cut line"
    if 'description=__doc__.split("\\n\\n")[0]' in source:
        assert first_paragraph(script).endswith((".", ")")), f"{script.name}: first paragraph ends mid-sentence"


@script_run
def test_dense_rate_help_shows_the_whole_first_paragraph():
    script = BENCHMARKS / "dense_rate.py"
    out = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=120,
                         check=True).stdout
    described = " ".join(out.split("\n\n", 2)[1].split())
    assert described == first_paragraph(script)


def test_dense_rate_pairs_0_prints_no_registration_table(capsys, monkeypatch):
    """``--pairs 0`` asks for no registration table: none is printed, not an empty table's header."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())   # the script's thread settings stay in this test
    import dense_rate

    dense_rate.registrations(None, 0, 1)   # no sequence is read either
    assert capsys.readouterr().out == ""


@script_run
@pytest.mark.parametrize("script", ["dense_rate.py", "dense_map_order.py", "dense_flat.py"])
def test_dense_benchmarks_refuse_fewer_than_2_frames_in_one_line(script):
    """``--frames 1`` is a usage error (exit 2, one line), not a traceback after the kernels load."""
    out = subprocess.run([sys.executable, str(BENCHMARKS / script), "--frames", "1"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "--frames must be at least 2" in out.stderr.strip().splitlines()[-1]


@script_run
def test_dense_flat_drives_a_short_path_out_and_back(tmp_path):
    """4 path frames out and 3 back through the dense frame loop, with and without the map's index:
    the two loops give the same poses, pairs and map sizes, and the table has a row per band."""
    env = {**os.environ, "ASSOCBENCH_CACHE": os.environ.get("ASSOCBENCH_CACHE", str(tmp_path / "cache"))}
    out = subprocess.run([sys.executable, str(BENCHMARKS / "dense_flat.py"), "--frames", "4", "--band", "2"],
                         capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "7 frames (4 out, 3 back)" in out.stdout and "the same poses, pairs and map sizes: True" in out.stdout
    rows = [line.split()[0] for line in out.stdout.splitlines() if line.strip().startswith(("0-1", "2-3"))]
    assert rows == ["0-1", "2-3"]
    assert out.stdout.count("fit with the index") == 2 and out.stdout.count("fit without the index") == 2
    assert "on a pixel" in out.stdout
    accuracy = [line for line in out.stdout.splitlines() if line.startswith("accuracy with the index: ATE ")]
    assert len(accuracy) == 1 and "over 7 frames" in accuracy[0] and "(median / p95) off the true surfaces" in accuracy[0]


@pytest.mark.parametrize("frames", [2, 60, 501])
def test_dense_flat_loop_spec_holds_the_way_back(frames, monkeypatch):
    """Fewer than 100 path frames made the loop's ``limits.frames`` (2N) lower than the path's 200
    frames: ``--frames 60`` ended in a traceback after rendering; 501 needs more than 1000."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat

    spec = dense_flat.loop_spec("crates", frames, [])
    assert spec.setting("dense").path_frames == max(frames, 200)


@pytest.mark.parametrize(("scene", "trajectory", "params"), [
    ("crates", "circle", {"turns": 0.175}), ("bays", "line", {"length": 11.25})])
def test_dense_benchmarks_drive_the_scene_own_path_at_its_default_speed(scene, trajectory, params, monkeypatch):
    """``dense_flat.py --scene bays`` drove bays on the crates circle (a path bays has no business
    on: 58 ICP failures, ATE 421 mm over the 999 frames): each scene now takes its own dense path,
    stretched to 500 frames at the default 200-frame path's speed a frame."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat

    seq = dense_flat.loop_spec(scene, 500, []).source.spec
    assert (seq.trajectory, seq.trajectory_params, seq.path_frames) == (trajectory, params, 500)
    assert dense_flat.loop_spec(scene, 50, []).source.spec.trajectory_params == {
        key: value * 200 / 500 for key, value in params.items()}


def test_dense_flat_growth_line_compares_the_first_and_last_band_of_the_way_out(monkeypatch):
    """The way back and frame 0 are left out: a way back twice as dear, and a frame 0 ten times,
    change nothing; the map doubled while the cost with the index held and without it rose 50 %."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat
    import pandas as pd

    frames = 6
    order = np.r_[np.arange(frames), np.arange(frames - 2, -1, -1)]
    out = np.arange(len(order)) < frames
    grown = np.where(out, 100_000 + 20_000 * order, 200_000)
    ours = pd.DataFrame({"map_points": grown, "stages_ms": np.where(out, 30.0, 60.0), "map_ms": np.where(out, 10.0, 20.0)})
    ours.loc[0, ["stages_ms", "map_ms"]] = 300.0
    whole = ours.copy()
    whole["stages_ms"] = np.where(out, 30.0 + 15.0 * (order >= 4), 90.0)
    line = dense_flat.growth_line(order, frames, 2, ours, whole)
    assert "the map 120k -> 190k points (x1.6)" in line
    assert "with the index, stages 30.0 -> 30.0 ms (+0 %), splat + fusion 10.0 -> 10.0 ms (+0 %)" in line
    assert "without it, stages 30.0 -> 45.0 ms (+50 %)" in line
    whole["map_ms"] = np.where(out, 10.0 - 4.0 * (order >= 4), 20.0)
    assert "splat + fusion 10.0 -> 6.0 ms (−40 %)" in dense_flat.growth_line(order, frames, 2, ours, whole)


@pytest.mark.parametrize(("frames", "band", "said"), [
    (40, 1000, "not measured"), (40, 30, "not measured"), (2, 1, "not measured"),
    (40, 1, "path frames 1-1 -> 39-39 (medians): the map 101k -> 139k points (x1.4)"),
    (40, 15, "path frames 1-14 -> 25-39 (medians)")])
def test_dense_flat_growth_line_measures_only_bands_apart(frames, band, said, monkeypatch):
    """``--band 1000 --frames 40`` compared a band with itself and printed 'the map x1.0, +0 %', a
    flat cost that was never measured; ``--band 1`` left the first band empty (frame 0 is left out)
    and printed 'nank -> ... (xnan)'. Bands that share a frame now say so; the line names its frames
    (with --frames 40 --band 15 the last band is 25-39, not the table's last row, 30-39)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat
    import pandas as pd

    order = np.r_[np.arange(frames), np.arange(frames - 2, -1, -1)]
    rec = pd.DataFrame({"map_points": 100_000 + 1000.0 * np.arange(len(order)), "stages_ms": 30.0 + order,
                        "map_ms": 10.0 + order})
    line = dense_flat.growth_line(order, frames, band, rec, rec)
    assert said in line and "nan" not in line and "x1.0" not in line


@script_run
def test_dense_rate_refuses_an_unknown_scene_in_one_line():
    """``dense_rate.py --scene nosuch`` printed the load line, then a traceback, exit 1."""
    out = subprocess.run([sys.executable, str(BENCHMARKS / "dense_rate.py"), "--scene", "nosuch", "--frames", "3"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr and out.stdout == ""
    assert "scene 'nosuch' not found" in out.stderr.strip().splitlines()[-1]


def test_dense_benchmarks_refuse_a_line_stretched_out_of_the_scene(monkeypatch):
    """The bays line stretched to the default speed is 15.75 m at 700 frames: from x = 1.42 m it
    passed the last landmark (14.25 m) near frame 570 and went through the end wall (15 m) near 604,
    ending at x = 17.2 m. It is refused before anything renders."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_rate

    from assocbench.errors import UserError

    with pytest.raises(UserError, match=r"--frames 700: the bays line .* at path frame 569 .* at most 569$"):
        dense_rate.sequence_spec("bays", 700)
    dense_rate.sequence_spec("bays", 569)   # frames 0-568 all lie within the landmarks
    assert dense_rate.sequence_spec("bays", 500).camera_path().trajectory_params == {"length": 11.25}
    assert dense_rate.sequence_spec("crates", 2000).camera_path().trajectory_params == {"turns": 0.7}   # a circle stays


@script_run
def test_dense_flat_refuses_an_unknown_scene_in_one_line():
    out = subprocess.run([sys.executable, str(BENCHMARKS / "dense_flat.py"), "--scene", "nosuch", "--frames", "3"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "scene 'nosuch' not found" in out.stderr.strip().splitlines()[-1]
    assert out.stdout == ""   # the load line came first, as if a measurement had begun


def test_dense_flat_fit_recovers_the_slopes_and_gives_one_where_visited_is_the_map(monkeypatch):
    """Without the index the splat visits the whole map: the two columns are one, and the fit's
    least-norm split printed that slope halved, twice (``2.40 per 100k visited + 2.40 per 100k map``
    for a 4.8 ms slope)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat
    import pandas as pd

    rng = np.random.default_rng(0)
    grown = np.cumsum(rng.integers(500, 2000, 40)) + 50_000
    visited = grown[:-1] - rng.integers(0, 30_000, 39)
    rec = pd.DataFrame({"map_points": grown, "predict_visited": np.r_[0, visited]})
    rec["ms"] = 3.0 + 10.0 * rec["predict_visited"] / 1e5 + 0.5 * rec["map_points"].shift(1).fillna(0) / 1e5
    np.testing.assert_allclose(dense_flat.fit(rec, "ms"), (3.0, 10.0, 0.5, 0.0), atol=1e-9)
    rec["predict_visited"] = np.r_[0, grown[:-1]]
    rec["ms"] = 2.0 + 4.8 * rec["predict_visited"] / 1e5
    a, b, c, sd = dense_flat.fit(rec, "ms")
    assert c is None and abs(a - 2.0) < 1e-9 and abs(b - 4.8) < 1e-9
    assert "4.80 ms per 100k map points (visited = the whole map)" in dense_flat.fit_line("x", "y", rec, "ms")


def test_dense_flat_refuses_a_loop_whose_method_failed(monkeypatch):
    """A frame whose method call failed (its pose held, ``error`` set) was counted among the ICP
    failures and its call's time among the loop's cost: the script ends (exit 1) naming the error."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat

    def records(seq, spec, calls, build):
        stages = {name: 0.001 for name in dense_flat.STAGES}
        yield {"frame": 0, "error": "", **stages}
        yield {"frame": 1, "error": "RuntimeError: boom", **stages}

    monkeypatch.setattr(dense_flat, "dense_records", records)
    with pytest.raises(SystemExit, match=r"failed on 1 of 2 frames \(first, frame 1: RuntimeError: boom\)"):
        dense_flat.records(None, "crates", 3, [])


def test_dense_flat_does_not_fit_a_line_through_too_few_frames(monkeypatch):
    """``--frames 2`` (3 loop frames) fitted 2 frames with 3 unknowns (2 without the index): the
    line passed through every point and printed ``residual sd 0.00 ms``, a perfect fit of
    meaningless slopes (``ms = 183.6 + -173.58 ms per 100k points visited + -176.06 ...``)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(os, "environ", os.environ.copy())
    import dense_flat
    import pandas as pd

    rec = pd.DataFrame({"map_points": [45_000, 47_000, 47_100], "predict_visited": [0, 39_000, 45_000],
                        "ms": [20.0, 46.9, 24.7]})
    line = dense_flat.fit_line("with the index", "stages", rec, "ms")
    assert "not fitted, 2 frames after the first for 3 unknowns" in line and "residual" not in line
    rec["predict_visited"] = [0, 45_000, 47_000]   # visited = the map before: one slope, 2 unknowns
    assert "not fitted, 2 frames after the first for 2 unknowns" in dense_flat.fit_line("x", "y", rec, "ms")
    rec = pd.concat([rec, pd.DataFrame({"map_points": [47_200], "predict_visited": [47_100], "ms": [30.0]})])
    line = dense_flat.fit_line("x", "y", rec.reset_index(drop=True), "ms")
    assert "residual sd" in line and "+ -" not in line


@script_run
def test_dense_fusion_ab_times_two_trees_and_says_whether_their_maps_agree(tmp_path):
    """The A/B of two fusion versions: one tree against itself builds one map (a hash each round,
    the same), and its table has every kernel's row. A folder that is no checkout is one line,
    exit 2, before any child runs."""
    repo = BENCHMARKS.parent
    env = {**os.environ, "ASSOCBENCH_CACHE": os.environ.get("ASSOCBENCH_CACHE", str(tmp_path / "cache"))}
    script = str(BENCHMARKS / "dense_fusion_ab.py")
    out = subprocess.run([sys.executable, script, str(repo), str(repo), "--pairs", "1", "--frames", "3", "--from", "1"],
                         capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "the same map bit for bit: yes" in out.stdout
    assert all(row in out.stdout for row in ("fuse", "merge pass", "cell pass", "samples' merge", "map hash"))
    for argv, said in (([str(tmp_path), str(repo)], "not a checkout of assocbench"),
                       ([str(repo), str(repo), "--from", "0"], "0 < --from < --frames")):
        bad = subprocess.run([sys.executable, script, *argv], capture_output=True, text=True, timeout=60)
        assert bad.returncode == 2 and "Traceback" not in bad.stderr and bad.stdout == ""
        assert said in bad.stderr.strip().splitlines()[-1]


def test_the_scripts_that_time_every_method_leave_out_those_that_need_descriptors():
    """associator_runtime.py, jcbb_anytime.py and pipeline_fps.py time every built-in on problems
    without descriptors: with appearance among them all three stopped with its ValueError."""
    from assocbench.associators.registry import BUILTINS, geometric_builtins

    assert set(BUILTINS) - set(geometric_builtins()) == {"appearance"}
    for script in ("associator_runtime.py", "jcbb_anytime.py", "pipeline_fps.py"):
        assert "geometric_builtins()" in (BENCHMARKS / script).read_text() and \
            "BUILTINS" not in (BENCHMARKS / script).read_text(), script
