"""The overview's rank rule: ties share their places, rows not ok rank last, the oracle is not ranked,
normalised ranks weigh scenarios with few and many methods alike."""

from __future__ import annotations

import numpy as np
from report_inputs import tiny_leaderboard

from assocbench.harness.report.ranking import overview, scenario_ranks
from assocbench.harness.report.suites import read_suite


def _row(scenario, method, f1, status="ok"):
    return {"scenario": scenario, "method": method, "f1": f1, "status": status}


def test_ties_share_places_not_ok_is_last_and_oracle_is_no_rival(tmp_path):
    folder = tiny_leaderboard(tmp_path / "lb", [
        _row("room/easy", "oracle", 1.0), _row("room/easy", "a", 0.9), _row("room/easy", "b", 0.9),
        _row("room/easy", "c", 0.5), _row("room/easy", "d", 0.99, "not ok: 3 failed frames"),
        _row("room/hard", "a", 0.2), _row("room/hard", "c", 0.4)])
    suite = read_suite(folder, "lb")
    suite.slug = "lb"
    ranks = scenario_ranks(suite).set_index(["scenario", "method"])
    assert ("room/easy", "oracle") not in ranks.index
    assert ranks.loc[("room/easy", "a"), "rank"] == ranks.loc[("room/easy", "b"), "rank"] == 1.5
    assert ranks.loc[("room/easy", "c"), "rank"] == 3 and ranks.loc[("room/easy", "d"), "rank"] == 4
    assert ranks.loc[("room/easy", "d"), "norm"] == 1.0 and not ranks.loc[("room/easy", "d"), "ok"]
    table = overview([suite]).set_index("method")
    # c: last of 4 (3rd place: norm 2/3) on easy, first of 2 on hard (0): mean 1/3
    assert np.isclose(table.loc["c", "overall"], (2 / 3 + 0) / 2)
    assert np.isclose(table.loc["a", "overall"], (0.5 / 3 + 1) / 2)
    assert table.loc["d", "not_ok"] == 1 and table.loc["c", "scenarios"] == 2
    assert list(table.index) == ["b", "c", "a", "d"]   # by overall: 1/6, 1/3, 7/12, 1


def test_a_closed_loop_ranks_by_ate_lowest_first(tmp_path):
    rows = [{"scenario": "park/easy-ekf", "method": m, "ate_rmse": ate, "f1": f1}
            for m, ate, f1 in (("a", 0.01, 0.5), ("b", 0.02, 0.9), ("c", float("nan"), 1.0))]
    suite = read_suite(tiny_leaderboard(tmp_path / "lb", rows), "lb")
    assert suite.kind == "loop" and suite.primary.key == "ate_rmse"
    ranks = scenario_ranks(suite).set_index("method")["rank"]
    assert list(ranks[["a", "b", "c"]]) == [1, 2, 3]   # no ATE: ranked after every value
