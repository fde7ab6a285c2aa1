"""benchmarks/sim_vs_real.py: each method's simulated and real place per back end, and Spearman's ρ."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture
def sim_vs_real(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    sys.modules.pop("sim_vs_real", None)
    import sim_vs_real

    return sim_vs_real


def leaderboard(rows) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["scenario", "method", "ate_rmse", "f1"])


def test_ranks_per_back_end_and_spearman(sim_vs_real, tmp_path):
    sim = leaderboard([("a/easy-ekf", "x", 1.0, 0.9), ("a/easy-ekf", "y", 2.0, 0.8), ("a/easy-ekf", "z", 3.0, 0.7),
                       ("b/hard-ekf", "x", 1.0, 0.9), ("b/hard-ekf", "y", 3.0, 0.8), ("b/hard-ekf", "z", 2.0, 0.7),
                       ("a/easy-isam2", "x", 9.0, 0.1), ("a/easy-ekf", "oracle", 0.1, 1.0)])
    real = leaderboard([("v/recorded-ekf", "x", 5.0, 0.5), ("v/recorded-ekf", "y", 4.0, 0.6),
                        ("v/recorded-ekf", "z", 3.0, 0.7), ("v/recorded-ekf", "oracle", 1.0, 1.0)])
    table, rho, scenarios = sim_vs_real.compare(sim, real, "ate_rmse", "ekf")
    assert scenarios == ["a/easy-ekf", "b/hard-ekf"] and "oracle" not in table.index
    assert table.loc["x", "sim place"] == 1 and table.loc["x", "real place"] == 3
    assert table.loc["y", "sim mean rank"] == 2.5 and table.loc["z", "sim mean rank"] == 2.5
    assert rho == pytest.approx(-0.866, abs=1e-3)   # y and z tie in simulation
    sim.to_csv(tmp_path / "sim.csv", index=False)
    real.to_csv(tmp_path / "real.csv", index=False)
    text = sim_vs_real.markdown(tmp_path / "sim.csv", tmp_path / "real.csv", ["ate_rmse", "f1"])
    assert "**ekf, ate_rmse** (Spearman ρ = -0.87 over 3 methods" in text and "**ekf, f1** (Spearman ρ = -1.00" in text


def test_one_table_of_every_place_and_rho(sim_vs_real):
    sim = leaderboard([("a/easy-ekf", "x", 1.0, 0.9), ("a/easy-ekf", "y", 2.0, 0.8), ("a/easy-ekf", "z", 3.0, 0.7),
                       ("a/easy-isam2", "x", 3.0, 0.9), ("a/easy-isam2", "y", 2.0, 0.8), ("a/easy-isam2", "z", 1.0, 0.7)])
    real = leaderboard([("v/recorded-ekf", "x", 5.0, 0.5), ("v/recorded-ekf", "y", 4.0, 0.6), ("v/recorded-ekf", "z", 3.0, 0.7),
                        ("v/recorded-isam2", "x", 5.0, 0.5), ("v/recorded-isam2", "y", 4.0, 0.6),
                        ("v/recorded-isam2", "z", 3.0, 0.7)])
    lines = sim_vs_real.places(sim, real, ["ate_rmse"], ["ekf", "isam2"])
    assert lines[0] == "| method | sim place ate_rmse (ekf / isam2) | real place ate_rmse (ekf / isam2) |"
    assert lines[2] == "| x | 1 / 3 | 3 / 3 |" and lines[-2] == "| **Spearman ρ** |  | **-1.00 / 1.00** |"
