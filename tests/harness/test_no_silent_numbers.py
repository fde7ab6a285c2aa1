"""No silent wrong numbers: bad settings are refused before anything runs, a broken run never reads
as a good one, and `check` passes only when it compared everything it was asked to."""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
import pytest
from cli.test_cli import assert_one_line_error

from assocbench import make_associator
from assocbench.cli.main import main
from assocbench.errors import UserError
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.suite import load_suite
from assocbench.harness.yamlfile import read_yaml
from assocbench.scoring.aggregate import OK, summarize


@pytest.mark.parametrize("setting,needles", [
    ("belief.sigma_rotation=.nan", ["belief.sigma_rotation", "finite", "nan"]),
    ("belief.sigma_position=.nan", ["belief.sigma_position", "nan"]),
    ("belief.sigma_landmark=.inf", ["belief.sigma_landmark", "inf"]),
    ("belief.sigma_rotation=nan", ["belief.sigma_rotation", "'nan'"]),      # the plain string
    ("belief.clutter=2.5", ["belief.clutter", "integer"]),
    ("belief.clutter=100000000000", ["belief.clutter", "limits.clutter"]),
    ("detector.quality=.nan", ["detector.quality"]),
    ("detector.max_features=0", ["detector.max_features"]),
    ("truth.gate_px=-1", ["truth.gate_px"]),
    ("truth.occlusion=xray", ["truth.occlusion", "ray, depth", "'xray'"]),
    ("trajectory_params.radius=.nan", ["trajectory_params.radius"]),
    ("trajectory_params=5", ["trajectory_params must be a mapping"]),
    ("trajectory_params.radius=-1", ["trajectory_params.radius", "(0, 100]"]),
    ("trajectory_params.turns=0", ["trajectory_params.turns"]),
    ("trajectory_params.bogus=1", ["takes no parameter 'bogus'", "radius"]),
    ("trajectory_params=abc", ["trajectory_params must be a mapping"]),
    ("params=[1, 2]", ["params must be a mapping"]),
    ("params.confidence=1.5", ["params.confidence", "(0, 1)"]),
    ("params.max_nodes=-5", ["params.max_nodes", ">= 1"]),
    ("params.prefix_test=1", ["params.prefix_test", "true or false"]),
    ("frames=true", ["frames", "integer"]),
    ("frames=1000000000", ["limits.frames"]),
    ("frames=100000", ["limits.frames"]),
    ("resolution=[0,0]", ["resolution width", "16"]),
    ("time_limit_s=.nan", ["time_limit_s"]),
    ("seed=-1", ["seed"]),
])
def test_bad_settings_are_refused_before_anything_runs(capsys, tmp_path, setting, needles):
    out = tmp_path / "out"
    frames = [] if setting.startswith("frames") else ["--frames", "2"]   # the flag would override --set
    assert_one_line_error(capsys, main(["run", *frames, "--set", setting, "--out", str(out)]), *needles)
    assert not out.exists()   # nothing created for a run that never started


def test_limits_can_be_raised():
    cfg = load_run_config(sets=["frames=6000", "limits.frames=10000"])
    assert len(run_spec(cfg).source) == 6000


@pytest.mark.parametrize("method,params", [
    ("mnn", {"confidence": 1.5}), ("jcbb", {"max_nodes": -5}), ("enn", {"gate": float("nan")}),
    ("ml", {"log_alpha": "x"}), ("lsa", {"threshold": float("inf")}), ("snn", {"confidence": 0}),
    ("ccda", {"max_nodes": 10**20}), ("jpda", {"max_events": 10**20}), ("rjc", {"seed": 2**64}),
])
def test_method_parameters_are_checked_when_the_method_is_built(method, params):
    with pytest.raises(UserError, match=f"params.{next(iter(params))}"):
        make_associator(method, **params)


def test_duplicate_yaml_keys_are_refused(tmp_path):
    path = tmp_path / "cfg.yaml"
    path.write_text("frames: 4\nbelief:\n  clutter: 2\n  clutter: 5\n")
    with pytest.raises(UserError, match="duplicate key 'clutter'"):
        read_yaml(path)


@pytest.mark.parametrize("body,needle", [
    ("methods: [mnn, {name: mnn, method: jcbb}]\nseeds: [0]\n", "duplicate method labels 'mnn'"),
    ("methods: [mnn]\nseeds: [0, 0]\n", "duplicate seeds 0"),
    ("methods: [mnn]\nseeds: [0]\nscenes: [room, room]\n", "duplicate scenes 'room'"),
    ("methods: [mnn]\nseeds: [0]\ntolerance: abc\n", "tolerance"),
    ("methods: [mnn]\nseeds: [0]\ntolerance: .nan\n", "tolerance"),
    ("methods: [{name: x, method: mnn, params: {confidence: 2}}]\nseeds: [0]\n", "params.confidence"),
    ("methods: [mnn]\nseeds: [true]\n", "seeds"),
])
def test_bad_suites_are_refused(tmp_path, body, needle):
    path = tmp_path / "suite.yaml"
    path.write_text("base: {frames: 2}\n" + body)
    with pytest.raises(UserError, match=needle):
        load_suite(path)


@pytest.mark.parametrize("source,needle", [
    ("def broken(:\n", "SyntaxError"),
    ("raise RuntimeError('no import for you')\n", "RuntimeError: no import for you"),
    ("import sys\nsys.exit(0)\n", "SystemExit"),
])
def test_plugins_that_fail_at_import_are_one_line_errors(capsys, tmp_path, monkeypatch, source, needle):
    (tmp_path / "badplug.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "badplug", raising=False)
    assert_one_line_error(capsys, main(["run", "--method", "badplug:X", "--frames", "2"]), "badplug:X", needle)


def _frames(**cols) -> pd.DataFrame:
    base = dict(n=[3, 3], tp=[1, 1], fp=[0, 0], fn=[0, 0], perfect=[True, True], surprisal=[0.0, 0.0],
                surprisal_true=[0.0, 0.0], jointly_compatible=[True, True], clutter_accepted=[0, 0],
                runtime_s=[1e-3, 1e-3], error=["", ""], timed_out=[False, False])
    return pd.DataFrame({**base, **cols})


@pytest.mark.parametrize("cols,status", [
    ({}, OK),
    ({"n": [0, 0], "tp": [0, 0]}, "no candidates in any frame"),
    ({"tp": [0, 0], "fn": [2, 2], "perfect": [False, False]}, "nothing associated"),
    ({"error": ["", "RuntimeError: boom"]}, "1/2 frames failed"),
    ({"n_true": [0, 0], "tp": [0, 0], "fp": [2, 2]}, "no true pair in any frame"),
    ({"n_true": [0, 0], "tp": [0, 0]}, "no true pair in any frame; nothing associated"),
])
def test_a_broken_run_never_reads_as_a_perfect_one(cols, status):
    s = summarize(_frames(**cols))
    assert s["status"] == status
    if status != OK:
        assert not (s["precision"] == 1 and s["recall"] == 1 and s["perfect"] == 1)
    if "n" in cols or "fn" in cols:
        assert np.isnan(s["precision"])   # nothing returned: no precision to speak of, not 1


def test_run_with_no_candidates_warns_and_exits_1(tmp_path, capsys):
    code = main(["run", "--frames", "2", "--set", "belief.map_fraction=0", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1 and "cannot be trusted" in err and "no candidates" in err
    assert pd.read_csv(tmp_path / "summary.csv").loc[0, "status"] == "no candidates in any frame"


def test_a_run_whose_truth_has_no_true_pair_is_not_ok(tmp_path, capsys):
    """Reproduction: ``assocbench run --set truth.gate_px=1e-300`` labels no feature with a landmark,
    so the truth has no true pair: recall had nothing to count, every pairing was false, yet the
    status was ok and the run exited 0."""
    code = main(["run", "--frames", "2", "--set", "truth.gate_px=1e-300", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1 and "cannot be trusted: no true pair in any frame" in err
    assert pd.read_csv(tmp_path / "summary.csv").loc[0, "status"] == "no true pair in any frame"


def test_default_run_folder_names_the_settings(tmp_path, monkeypatch, capsys):
    """A quick experiment never overwrites the main job's CSVs."""
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--frames", "3"]) == 0
    assert main(["run", "--frames", "2"]) == 0
    runs = sorted(p.name for p in (tmp_path / "results" / "runs").iterdir())
    assert len(runs) == 2 and all(r.startswith("room-jcbb-seed0-") for r in runs)
    said = capsys.readouterr().out
    assert all(f"results/runs/{r}/summary.csv" in said for r in runs)   # it says where they went


def test_a_failed_run_leaves_no_output_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--method", "nosuch", "--frames", "2"]) == 2
    assert not (tmp_path / "results").exists()


# -- check ----------------------------------------------------------------------------------------

PLUGINS = '''
import numpy as np
from assocbench import Associator, make_associator

class Raises(Associator):
    def associate(self, problem):
        raise RuntimeError("boom")

class Silent(Associator):
    """Associates nothing at all."""
    def associate(self, problem):
        return self.empty(problem)
'''


@pytest.fixture(scope="module")
def ci_setup(tmp_path_factory):
    """A two-frame suite of one method, its baseline written by check --update, and plugins."""
    root = tmp_path_factory.mktemp("check")
    (root / "check_plugins.py").write_text(PLUGINS)
    sys.path.insert(0, str(root))
    suite = root / "suite.yaml"
    suite.write_text("base: {frames: 3, resolution: [320, 240]}\nscenes: [room]\n"
                     "difficulties: {easy: {belief: {sigma_position: 0.03}}}\nmethods: [{name: m, method: mnn}]\n"
                     "seeds: [0]\n")
    baseline = root / "baseline.csv"
    assert main(["check", "--suite", str(suite), "--baseline", str(baseline), "--update", "--quiet"]) == 0
    yield root, suite, baseline
    sys.path.remove(str(root))


def _check(capsys, suite, baseline, *extra) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["check", "--suite", str(suite), "--baseline", str(baseline), "--quiet", *extra])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def _variant(root, suite, name, **replace) -> object:
    text = suite.read_text()
    for old, new in replace.items():
        text = text.replace(old, new)
    path = root / name
    path.write_text(text)
    return path


def test_check_passes_on_its_own_baseline(ci_setup, capsys):
    root, suite, baseline = ci_setup
    code, out = _check(capsys, suite, baseline)
    assert code == 0 and "1 scenario × method rows compared" in out


@pytest.mark.parametrize("method,why", [
    ("check_plugins:Raises", "frames failed"),
    ("check_plugins:Silent", "nothing associated"),
])
def test_check_fails_on_a_run_that_cannot_be_trusted(ci_setup, capsys, method, why):
    root, suite, baseline = ci_setup
    code, out = _check(capsys, _variant(root, suite, "v.yaml", **{"method: mnn": f"method: '{method}'"}), baseline)
    assert code == 1 and why in out


def test_check_fails_on_no_candidates(ci_setup, capsys):
    root, suite, baseline = ci_setup
    variant = _variant(root, suite, "nocand.yaml", **{"sigma_position: 0.03": "sigma_position: 0.03, map_fraction: 0"})
    code, out = _check(capsys, variant, baseline)
    assert code == 1 and "no candidates" in out


def test_check_fails_on_a_row_it_could_not_compare(ci_setup, capsys):
    root, suite, baseline = ci_setup
    renamed = _variant(root, suite, "renamed.yaml", **{"name: m,": "name: other,"})
    code, out = _check(capsys, renamed, baseline)
    assert code == 1 and "not in the baseline" in out and "in the baseline but not in the suite" in out


@pytest.mark.parametrize("tolerance,needle", [("nan", "--tolerance"), ("-1", "--tolerance"), ("inf", "--tolerance")])
def test_check_refuses_a_meaningless_tolerance(ci_setup, capsys, tolerance, needle):
    root, suite, baseline = ci_setup
    assert_one_line_error(capsys, main(["check", "--suite", str(suite), "--baseline", str(baseline),
                                        "--tolerance", tolerance, "--quiet"]), needle)


@pytest.mark.parametrize("damage,needle", [
    (lambda text: text.splitlines()[0] + "\n", "no rows"),                        # header only
    (lambda text: text[: text.rindex(",") - 2], "not a number"),                 # truncated mid-row
    (lambda text: text.replace(text.splitlines()[1].split(",")[2], "nan", 1), "not a number"),
    (lambda text: text.replace(text.splitlines()[1].split(",")[2], "abc", 1), "not a number"),
    (lambda text: text + text.splitlines()[1] + "\n", "twice"),
    (lambda text: "", "not a readable CSV"),
])
def test_check_refuses_a_damaged_baseline(ci_setup, capsys, tmp_path, damage, needle):
    root, suite, baseline = ci_setup
    bad = tmp_path / "baseline.csv"
    bad.write_text(damage(baseline.read_text()))
    assert_one_line_error(capsys, main(["check", "--suite", str(suite), "--baseline", str(bad), "--quiet"]), needle)


def test_a_full_disk_is_one_line_and_leaves_no_half_written_run(tmp_path, monkeypatch, capsys):
    """ENOSPC while writing summary.csv: frames.csv must not be left behind as if the run were complete."""
    import errno

    real = pd.DataFrame.to_csv

    def full_disk(self, path=None, *args, **kwargs):
        if "status" in self.columns:   # the one-row summary
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, path, *args, **kwargs)

    monkeypatch.setattr(pd.DataFrame, "to_csv", full_disk)
    out = tmp_path / "out"
    assert_one_line_error(capsys, main(["run", "--frames", "2", "--out", str(out)]), "No space left")
    assert not list(out.glob("*.csv")) and not list(out.glob(".*"))


def test_a_leaderboard_row_counts_failed_frames_over_all_seeds():
    """A method failing in two seeds' runs: the status counts both, as the failures column does."""
    from assocbench.scoring.aggregate import leaderboard_table

    runs = [dict(scenario="room/easy", method="m", status="6/6 frames failed; nothing associated", precision=np.nan,
                 recall=0.0, f1=np.nan, perfect=0.0, surprisal_gap=0.0, runtime_median_ms=1.0, frames=6, failures=6,
                 timed_out=0) for _ in range(2)]
    row = leaderboard_table(pd.DataFrame(runs)).iloc[0]
    assert row["status"] == "12/12 frames failed; nothing associated in 2 of 2 seeds"
    assert np.isnan(row["precision"])   # NaN is kept, not averaged away


def test_a_folder_given_as_config_is_named_as_a_folder(tmp_path):
    with pytest.raises(UserError, match="is a folder; pass a YAML file"):
        read_yaml(tmp_path)


def test_a_row_that_is_not_ok_never_ranks_first():
    """Sorted by F1 (or a loop's ATE), a run with failed frames still goes below every ok row."""
    from assocbench.scoring.aggregate import leaderboard_table

    rows = [{"scenario": "room/easy", "method": m, "seed": 0, "precision": p, "recall": p, "f1": p, "perfect": p,
             "surprisal_gap": 0.0, "runtime_median_ms": 1.0, "frames": 10, "failures": f, "timed_out": 0,
             "status": "ok" if not f else f"{f}/10 frames failed"}
            for m, p, f in (("broken", 1.0, 3), ("good", 0.9, 0), ("fair", 0.8, 0))]
    table = leaderboard_table(pd.DataFrame(rows))
    assert list(table["method"]) == ["good", "fair", "broken"]
    loop = pd.DataFrame(rows).assign(ate_rmse=[0.01, 0.05, 0.09], rot_rmse_deg=0.1, anees=6.0, anees_lo=5.0,
                                     anees_hi=7.0, diverged_at=-1, map_size=5, duplicates=0, false_landmarks=0,
                                     map_rmse=0.01, new_landmarks=0, no_depth=0)
    assert list(leaderboard_table(loop)["method"]) == ["good", "fair", "broken"]


def test_settings_in_scientific_notation_are_numbers():
    """YAML 1.1 reads 5e-1 as a string; settings read it as the number people meant."""
    from assocbench.harness.yamlfile import parse_sets

    assert parse_sets(["a=5e-1", "b=-2E-3", "c=1e300", "d=abc"]) == {"a": 0.5, "b": -0.002, "c": 1e300, "d": "abc"}
