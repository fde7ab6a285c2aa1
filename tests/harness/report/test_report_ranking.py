"""The overview's rank rule: methods compared only over the blocks (scenario x seed) they all ran, a
method that missed some listed apart; places decided by the Friedman / Nemenyi test, so methods
within noise share one; a diverged or not-ok run never wins its block; the oracle is no rival."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from report_inputs import runs_leaderboard, tiny_leaderboard

from assocbench.errors import UserError
from assocbench.harness.leaderboard import write_leaderboard
from assocbench.harness.report import build_report
from assocbench.harness.report.ranking import rank, rankings
from assocbench.harness.report.suites import read_suite
from assocbench.tracks.registry import get_track

SCENARIOS = [f"{scene}/{d}" for scene in ("room", "corridor", "checkerboard") for d in ("easy", "medium", "hard")]


def _ranking_rows(index_html: str) -> dict[str, list[str]]:
    """The overview's first ranking table: method -> the text of its other cells."""
    table = index_html[index_html.index('<table class="ranking">'):].split("</table>")[0]
    rows = {}
    for row in re.findall(r"<tr>(.*?)</tr>", table.split("<tbody>")[1], flags=re.S):
        cells = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", row, flags=re.S)]
        rows[cells[0]] = cells[1:]
    return rows


def _camera_runs(f1: dict[str, list[float]], seeds=(0, 1, 2)) -> list[dict]:
    """Open-loop runs: each method's F1 per scenario (``SCENARIOS`` order), the same at every seed
    but for a small seed-dependent wobble."""
    return [{"scenario": sc, "method": m, "seed": s, "status": "ok", "f1": v - 1e-4 * s * (k % 2)}
            for m, values in f1.items() for k, (sc, v) in enumerate(zip(SCENARIOS, values)) for s in seeds]


def test_a_copy_absent_from_the_hard_scenarios_cannot_outrank_the_method_it_copies(tmp_path):
    # the case: a test associator returning exactly MNN's answers, not run in the hard scenarios,
    # ranked above MNN because MNN's hard scenarios pulled MNN's mean down
    rows = _camera_runs({"jcbb": [0.99] * 9, "mnn": [0.95, 0.9, 0.6] * 3, "snn": [0.97, 0.8, 0.7] * 3,
                         "lsa": [0.96, 0.85, 0.65] * 3})
    rows += [r | {"method": "copy"} for r in rows if r["method"] == "mnn" and not r["scenario"].endswith("hard")]
    folder = runs_leaderboard(tmp_path / "camera", pd.DataFrame(rows))
    cells = _ranking_rows(build_report([folder])["index.html"].decode())
    assert cells["copy"][0] == "left out"
    ranking = rank([read_suite(folder, "camera")], "camera", "camera")
    assert "copy" not in set(ranking.table["method"])
    assert ranking.left_out == {"copy": "did not run room/hard, corridor/hard, checkerboard/hard"}
    assert ranking.test.blocks == 27   # every scenario at every seed, not only the copy's 18

    # run everywhere, the copy is MNN's equal: the same mean rank, the same place
    rows += [r | {"method": "copy"} for r in rows if r["method"] == "mnn" and r["scenario"].endswith("hard")]
    table = rank([read_suite(runs_leaderboard(tmp_path / "all", pd.DataFrame(rows)), "all")], "all", "all").table
    mine = table.set_index("method")
    assert mine.loc["copy", "mean_rank"] == mine.loc["mnn", "mean_rank"]
    assert mine.loc["copy", "place"] == mine.loc["mnn", "place"]


def test_two_methods_within_noise_share_a_place_and_a_clear_loser_does_not(tmp_path):
    # a beats b in 12 of the 18 blocks by 0.001 m of ATE, b beats a in the other 6: a's mean ATE is lower, but
    # a mean rank of 1.33 against 1.67 is well within chance over 18 blocks; c is last in every block
    rows = []
    for k, scenario in enumerate(f"{s}-ekf" for s in SCENARIOS[:6]):
        for seed in range(3):
            a_wins = (k + seed) % 3 != 0
            rows += [{"scenario": scenario, "method": "a", "seed": seed, "ate_rmse": 0.010 if a_wins else 0.011},
                     {"scenario": scenario, "method": "b", "seed": seed, "ate_rmse": 0.011 if a_wins else 0.0105},
                     {"scenario": scenario, "method": "c", "seed": seed, "ate_rmse": 0.05}]
    rows = [r | {"status": "ok", "diverged": 0} for r in rows]
    folder = runs_leaderboard(tmp_path / "planar", pd.DataFrame(rows))
    cells = _ranking_rows(build_report([folder])["index.html"].decode())
    assert cells["a"][0].startswith("1 (1.33)") and cells["b"][0].startswith("1 (1.67)")
    assert cells["c"][0].startswith("3 (3.00)")
    means = pd.DataFrame(rows).groupby("method")["ate_rmse"].mean()
    assert means["a"] < means["b"]   # the means alone would have put a ahead


def test_a_diverged_run_never_wins_its_block(tmp_path):
    # d has the lowest ATE everywhere but diverged at seed 0 of every scenario: last in those blocks
    rows = [{"scenario": f"park/{sc}-ekf", "method": m, "seed": s, "status": "ok", "ate_rmse": ate,
             "diverged": int(m == "d" and s == 0)}
            for sc in ("easy", "hard") for s in (0, 1) for m, ate in (("d", 0.001), ("e", 0.01), ("f", 0.02))]
    rows.append({"scenario": "park/hard-ekf", "method": "oracle", "seed": 0, "status": "ok", "ate_rmse": 0.0,
                 "diverged": 0})
    rows.append(rows.pop(-1) | {"seed": 1})   # the oracle: a reference, never a rival
    suite = read_suite(runs_leaderboard(tmp_path / "planar", pd.DataFrame(rows)), "planar")
    table = rank([suite], "planar", "planar").table.set_index("method")
    assert "oracle" not in table.index
    assert table.loc["d", "mean_rank"] == (1 + 1 + 3 + 3) / 4 and table.loc["d", "last"] == 2
    assert table.loc["e", "mean_rank"] == (1 + 1 + 2 + 2) / 4


def test_a_run_not_ok_or_without_a_value_ranks_last_tied_with_its_like(tmp_path):
    rows = [{"scenario": "room/easy", "method": m, "seed": 0, "status": status, "f1": f1}
            for m, f1, status in (("a", 0.9, "ok"), ("b", 0.99, "3/30 frames failed"), ("c", np.nan, "ok"),
                                  ("d", 0.5, "ok"))]
    suite = read_suite(runs_leaderboard(tmp_path / "camera", pd.DataFrame(rows)), "camera")
    table = rank([suite], "camera", "camera").table.set_index("method")
    assert table["mean_rank"].to_dict() == {"a": 1.0, "d": 2.0, "b": 3.5, "c": 3.5}
    assert table["last"].to_dict() == {"a": 0, "d": 0, "b": 1, "c": 1}


def test_overall_ranks_only_the_methods_of_every_suite_and_says_why_the_others_are_apart(tmp_path):
    camera = _camera_runs({"jcbb": [0.99] * 9, "mnn": [0.9] * 9, "rjc": [0.995] * 9})
    planar = [{"scenario": "park/easy-ekf", "method": m, "seed": s, "status": "ok", "ate_rmse": a, "diverged": 0}
              for s in (0, 1) for m, a in (("jcbb", 0.01), ("mnn", 0.02), ("naive4", 0.005))]
    suites = [read_suite(runs_leaderboard(tmp_path / name, pd.DataFrame(rows)), name)
              for name, rows in (("camera", camera), ("planar", planar))]
    for s, slug in zip(suites, ("camera", "planar")):
        s.title = s.slug = slug
    overall = rankings(suites, "Feature associators")[-1]
    assert list(overall.table["method"]) == ["jcbb", "mnn"] and overall.test.blocks == 27 + 2
    assert overall.left_out == {"naive4": "not in camera", "rjc": "not in planar"}


def test_a_folder_of_means_ranks_its_scenarios_and_says_the_seeds_could_not_be_blocks(tmp_path):
    rows = [{"scenario": sc, "method": m, "f1": f1, "status": "ok", "seeds": 3}
            for sc in SCENARIOS for m, f1 in (("jcbb", 0.99), ("mnn", 0.9))]
    index = build_report([tiny_leaderboard(tmp_path / "old", rows)])["index.html"].decode()
    assert "2 methods over 9 blocks (its 9 scenarios, means over seeds: no runs.csv" in index
    assert "img/ranks/camera-open-loop.png" in index


def test_runs_that_do_not_match_their_means_are_refused(tmp_path):
    folder = runs_leaderboard(tmp_path / "camera", pd.DataFrame(_camera_runs({"jcbb": [0.9] * 9, "mnn": [0.8] * 9})))
    runs = pd.read_csv(folder / "runs.csv")
    runs[runs["method"] != "mnn"].to_csv(folder / "runs.csv", index=False)
    with pytest.raises(UserError, match="runs.csv does not hold the runs of the leaderboard.csv beside it"):
        build_report([folder])


def test_leaderboard_writes_every_run_and_the_report_tests_over_them(tmp_path):
    summaries = pd.DataFrame([
        {"scenario": sc, "scene": sc.split("/")[0], "difficulty": sc.split("/")[1], "method": m, "seed": s,
         "status": "ok", "precision": f1, "recall": f1, "f1": f1, "perfect": 0.5, "surprisal_gap": 1.0,
         "runtime_median_ms": 0.2, "frames": 10, "failures": 0, "timed_out": 0, "error": ""}
        for sc in SCENARIOS[:3] for s in (0, 1) for m, f1 in (("jcbb", 0.99 - 0.01 * s), ("mnn", 0.9))])
    frames = pd.DataFrame({"method": "jcbb", "n": np.arange(10, 40), "runtime_s": 1e-4})
    paths = write_leaderboard(summaries, frames, tmp_path, get_track("camera"))
    runs = pd.read_csv(paths["runs"])
    assert list(runs.columns[:3]) == ["scenario", "method", "seed"] and len(runs) == len(summaries)
    suite = read_suite(tmp_path, "camera")
    ranking = rank([suite], "camera", "camera")
    assert ranking.per_seed and ranking.test.blocks == 3 * 2   # scenarios x seeds, not 3 means
