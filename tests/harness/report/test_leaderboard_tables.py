"""Tables made from leaderboards by benchmark scripts: sim_vs_real.py (each method's mean rank on a
simulated leaderboard against a recorded one, ranked as the report ranks, over the shared methods,
with Spearman's correlation) and call_sizes.py (time per call and the largest problem, per method)."""

from __future__ import annotations

from pathlib import Path

import pytest
from report_inputs import tiny_leaderboard

BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"


@pytest.fixture
def script(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import sim_vs_real

    return sim_vs_real


def board(folder: Path, scene: str, f1: dict[str, list[float]], status: dict | None = None) -> Path:
    """A leaderboard of ``scene`` at easy and hard: each method's F1 in each."""
    rows = [{"scenario": f"{scene}/{d}", "method": m, "f1": v[k], "status": (status or {}).get((m, d), "ok")}
            for m, v in f1.items() for k, d in enumerate(("easy", "hard"))]
    return tiny_leaderboard(folder, rows)


def test_the_same_order_is_rho_one_and_the_reverse_minus_one(tmp_path, script, capsys):
    sim = board(tmp_path / "sim", "room", {"a": [0.9, 0.8], "b": [0.7, 0.6], "c": [0.5, 0.4], "d": [0.3, 0.2]})
    same = board(tmp_path / "same", "checkerboard", {"a": [0.6, 0.5], "b": [0.5, 0.4], "c": [0.4, 0.3], "d": [0.1, 0.0]})
    reverse = board(tmp_path / "rev", "corridor", {"a": [0.1, 0.0], "b": [0.2, 0.1], "c": [0.3, 0.2], "d": [0.4, 0.3]})
    assert script.main([str(sim), str(same)]) == 0
    out = capsys.readouterr().out
    assert "ρ = +1.00 over 4 methods (a, b, c, d)" in out and "| a | 0.850 | 1.00 | 0.550 | 1.00 | +0.00 |" in out
    assert script.main([str(sim), str(reverse)]) == 0
    assert "ρ = -1.00" in capsys.readouterr().out


def test_only_shared_methods_are_ranked_and_a_not_ok_row_ranks_last(tmp_path, script, capsys):
    """e is only simulated and f only real: both left out, the others re-ranked among themselves; c
    not ok on the real easy scenario ranks last there whatever its F1 (as the report ranks)."""
    sim = board(tmp_path / "sim", "room", {"a": [0.9, 0.9], "b": [0.8, 0.8], "c": [0.7, 0.7], "e": [1.0, 1.0]})
    real = board(tmp_path / "real", "checkerboard", {"a": [0.9, 0.9], "b": [0.8, 0.8], "c": [0.95, 0.7],
                                                      "f": [1.0, 1.0]}, status={("c", "easy"): "failed frames"})
    assert script.main([str(sim), str(real)]) == 0
    out = capsys.readouterr().out
    assert "over 3 methods (a, b, c)" in out and "| c | 0.700 | 3.00 | 0.825 | 3.00 | +0.00 |" in out
    real = board(tmp_path / "nan", "checkerboard", {"a": [0.9, 0.9], "b": [0.8, 0.8], "c": [0.95, float("nan")]},
                 status={("c", "hard"): "failed frames"})
    assert script.main([str(sim), str(real)]) == 0
    assert "| c | 0.700 | 3.00 | n/a | 2.00 | -1.00 |" in capsys.readouterr().out   # no mean of the 0.95 alone
    assert "| easy | +1.00 | +1.00 | +1.00 |" in out


def test_back_ends_are_compared_apart_by_each_metric_asked_and_a_diverged_run_keeps_its_value(tmp_path, script, capsys):
    """--by backend: the ekf scenarios against the ekf ones, isam2 against isam2; by ATE (lower is
    better) and F1; x diverged on the real ekf run, yet ranks by its ATE (the report would rank it last)."""
    def rows(scene, difficulty, values, diverged=()):
        return [{"scenario": f"{scene}/{difficulty}", "method": m, "ate_rmse": a, "f1": f, "status": "ok",
                 "diverged": int(m in diverged)} for m, (a, f) in values.items()]

    sim = tiny_leaderboard(tmp_path / "sim", rows("park", "easy-ekf", {"x": (1, .9), "y": (2, .8), "z": (3, .7)})
                           + rows("post_grid", "hard-ekf", {"x": (1, .9), "y": (3, .8), "z": (2, .7)})
                           + rows("park", "easy-isam2", {"x": (3, .9), "y": (2, .8), "z": (1, .7)}))
    real = tiny_leaderboard(tmp_path / "real", rows("victoria_park", "whole-ekf", {"x": (5, .5), "y": (4, .6), "z": (3, .7)}, "x")
                            + rows("victoria_park", "whole-isam2", {"x": (5, .5), "y": (4, .6), "z": (3, .7)}))
    assert script.main([str(sim), str(real), "--by", "backend", "--metric", "ate_rmse", "f1"]) == 0
    out = capsys.readouterr().out
    ekf, isam2 = out.split("### ATE, back end isam2")[0], out.split("### ATE, back end isam2")[1].split("### F1")[0]
    assert "| x | 1.000 | 1.00 | 5.000 | 3.00 | +2.00 |" in ekf and "ρ = -0.87 over 3 methods" in ekf  # y, z tie in sim
    assert "2 simulated scenarios" in ekf and "ρ = +1.00" in isam2 and "1 simulated scenario (park" in isam2
    assert "### F1, back end ekf" in out and "### F1, back end isam2" in out
    assert script.main([str(sim), str(real), "--metric", "ate"]) == 2
    assert "has no column 'ate': give a metric both leaderboards have" in capsys.readouterr().err


def test_too_few_shared_methods_or_an_unshared_one_asked_for_is_one_line(tmp_path, script, capsys):
    sim = board(tmp_path / "sim", "room", {"a": [0.9, 0.9], "b": [0.8, 0.8], "c": [0.7, 0.7]})
    real = board(tmp_path / "real", "checkerboard", {"a": [0.9, 0.9], "b": [0.8, 0.8], "x": [0.7, 0.7]})
    assert script.main([str(sim), str(real)]) == 2
    assert "share 2 methods (a, b): a rank correlation needs 3 or more" in capsys.readouterr().err
    assert script.main([str(sim), str(real), "--methods", "a", "c"]) == 2
    assert "method c is not ranked on both leaderboards" in capsys.readouterr().err


def test_call_sizes_reads_every_stored_run_of_a_leaderboard(tmp_path, monkeypatch, capsys):
    """benchmarks/call_sizes.py: per method its calls, time per call and the largest n and m, from
    the runs a leaderboard stored (through their manifests), and its failed and timed-out frames."""
    import json

    import pandas as pd

    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import call_sizes

    jobs = tmp_path / "lb" / "runs"
    jobs.mkdir(parents=True)
    for key, (n, m, seconds, failures) in {"a": (10, 50, [0.001, 0.003], 1), "b": (30, 20, [0.002, 0.005], 0)}.items():
        # as the store writes them: the method only in the manifest's run name
        pd.DataFrame({"n": [n, n - 1], "m": [m, m], "runtime_s": seconds}).to_csv(jobs / f"{key}.f.csv")
        pd.DataFrame({"failures": [failures], "timed_out": [2]}).to_csv(jobs / f"{key}.s.csv")
        files = {"frames": {"name": f"{key}.f.csv"}, "summary": {"name": f"{key}.s.csv"}}
        (jobs / f"{key}.manifest.json").write_text(json.dumps({"run": f"mnn on room/easy seed {key}", "files": files}))
    (jobs / "stale.f.csv").write_text("method,n,m,runtime_s\nmnn,999,999,9\n")   # named by no manifest
    assert call_sizes.main([str(tmp_path / "lb")]) == 0
    assert "| mnn | 4 | 2.500 | 4.700 | 5.000 | 30 | 50 | 1 | 4 |" in capsys.readouterr().out
    assert call_sizes.main([str(tmp_path)]) == 2
    assert "holds no stored run" in capsys.readouterr().err
