"""``check`` guards the planar iSAM2 back end (issue 26 item 1): the smoothed ATE is compared with
the suite's ``ate_tolerance`` where the baseline has it, and assocbench/configs/planar_isam2_ci.yaml
is one of check's default suites wherever gtsam is installed (said, not silent, where it is not)."""

from __future__ import annotations

import importlib.util
import math

import pandas as pd
import pytest

from assocbench.cli import check_cmd
from assocbench.cli.main import main
from assocbench.errors import UserError
from assocbench.harness.check import compare, read_baseline
from assocbench.tracks.registry import get_track

ROW = {"scenario": "park/hard", "method": "lsa", "precision": 0.96, "recall": 0.95, "f1": 0.955, "perfect": 0.66,
       "ate_rmse": 0.0029, "ate_smoothed": 0.0026, "status": "ok"}
GUARDS = get_track("planar").guards(loop=True)


def findings(**current) -> pd.DataFrame:
    base = pd.DataFrame([ROW]).drop(columns="status")
    return compare(pd.DataFrame([ROW | current]), base, GUARDS, {"tolerance": 0.02, "ate_tolerance": 0.005},
                   [("park/hard", "lsa")])


def test_a_smoothed_ate_risen_past_the_tolerance_is_a_finding():
    assert findings(ate_smoothed=0.0026 + 0.0049).empty
    bad = findings(ate_smoothed=0.0026 + 0.0051)
    assert list(bad["metric"]) == ["ate_smoothed"] and list(bad["why"]) == ["regressed"]
    assert list(findings(ate_smoothed=math.nan)["why"]) == ["not a finite number"]


def test_a_damaged_smoothed_ate_in_the_baseline_is_refused(tmp_path):
    path = tmp_path / "baseline.csv"
    pd.DataFrame([ROW | {"ate_smoothed": "x"}]).drop(columns="status").to_csv(path, index=False)
    with pytest.raises(UserError, match="ate_smoothed is 'x'"):
        read_baseline(path, GUARDS, "planar_isam2_ci")


def test_a_baseline_without_the_smoothed_ate_is_compared_on_the_rest(tmp_path):
    path = tmp_path / "baseline.csv"
    pd.DataFrame([ROW]).drop(columns=["status", "ate_smoothed"]).to_csv(path, index=False)
    assert "ate_smoothed" not in read_baseline(path, GUARDS, "planar_ci")


def default_suites(monkeypatch, gtsam: bool) -> list[str]:
    """The suite names ``check`` with no ``--suite`` runs (the runs themselves stubbed out)."""
    ran = []
    monkeypatch.setattr(check_cmd, "check_suite", lambda suite, *rest: ran.append(suite.name) or 0)
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: find_spec(name, *a) if gtsam or name != "gtsam"
                        else None)
    assert main(["check", "--quiet"]) == 0
    return ran


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="gtsam not installed")
def test_check_runs_the_isam2_suite_by_default_where_gtsam_is_installed(monkeypatch, capsys):
    assert "planar_isam2_ci" in default_suites(monkeypatch, gtsam=True)
    assert "planar_isam2_ci" not in default_suites(monkeypatch, gtsam=False)
    assert "planar_isam2_ci skipped: gtsam is not installed" in capsys.readouterr().out


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="gtsam not installed")
def test_the_isam2_suite_passes_against_its_committed_baseline(capsys):
    assert main(["check", "--suite", "planar_isam2_ci", "--quiet"]) == 0
    assert "4 scenario × method rows compared" in capsys.readouterr().out
