"""``assocbench check`` guards a clone: outside one it says so in one line, before running anything."""

from __future__ import annotations

import shutil
from pathlib import Path

from test_cli import ROOT, run_cli

from assocbench.cli import check_cmd
from assocbench.cli.main import main


def test_check_outside_a_clone_says_it_guards_a_clone(tmp_path):
    """Run from a folder with no results/ (an installed package, not a clone): exit 2, one line
    that names the clone, --baseline and --update, and no traceback."""
    proc = run_cli("check", "--quiet", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr
    assert err.count("\n") == 1 and err.startswith("assocbench: error: baseline results/baseline.csv not found"), err
    assert "Traceback" not in err
    for needle in (str(tmp_path), "guards a clone", "clone's root", "--baseline PATH", "--update"):
        assert needle in err, err
    assert not (tmp_path / "results").exists()   # nothing written


def test_every_baseline_is_checked_before_any_suite_runs(tmp_path, monkeypatch, capsys):
    """With only the ci suite's baseline present, the missing loop_ci baseline is reported before
    the ci suite runs (it used to run for a minute first)."""
    (tmp_path / "results").mkdir()
    shutil.copy(Path(ROOT) / "results" / "baseline.csv", tmp_path / "results" / "baseline.csv")
    monkeypatch.chdir(tmp_path)
    ran = []
    monkeypatch.setattr(check_cmd, "run_suite", lambda suite, *a, **k: ran.append(suite.name))
    assert main(["check", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "baseline results/baseline_loop_ci.csv not found" in err and "guards a clone" in err, err
    assert ran == []


def test_a_named_baseline_that_is_missing_names_the_path_not_the_clone(tmp_path, capsys):
    assert main(["check", "--baseline", str(tmp_path / "mine.csv")]) == 2
    err = capsys.readouterr().err
    assert "mine.csv not found" in err and "--update" in err and "clone" not in err, err


def test_the_verdict_gives_each_guarded_column_its_tolerance_in_its_unit():
    """The ok line printed one figure, "within tolerance 0.02", for every suite, while the dense
    suite's ATE and map error may rise by 2 mm and the loop's ATE by 0.01 m."""
    from assocbench.tracks.base import ACCURACY_GUARDS, ATE_GUARD
    from assocbench.tracks.registry import get_track

    tolerances = {"tolerance": 0.02, "ate_tolerance": 0.002}
    dense = check_cmd.tolerance_text(get_track("dense").guards(False), tolerances)
    assert dense == "precision, recall may fall by 0.02; ate_mm, map_median_mm may rise by 2 mm"
    loop = check_cmd.tolerance_text((*ACCURACY_GUARDS, ATE_GUARD), {"tolerance": 0.02, "ate_tolerance": 0.01})
    assert loop == "precision, recall, f1, perfect may fall by 0.02; ate_rmse may rise by 0.01 m"


def test_list_marks_every_suite_check_runs_by_default(capsys):
    """The suites ``check`` runs by default are each track's ``ci`` ones, shown by ``assocbench list
    suites`` (the help once listed them by hand and left out planar_isam2_ci)."""
    from assocbench.tracks.registry import iter_tracks

    assert main(["list", "suites"]) == 0
    out = capsys.readouterr().out
    marked = {line.split()[0] for line in out.splitlines()[1:] if line.endswith("(check)")}
    assert marked == set(check_cmd.default_suites()) == {
        name for track in iter_tracks() for name, entry in track.suites().items() if entry.ci}
    assert "planar_isam2_ci" in marked
