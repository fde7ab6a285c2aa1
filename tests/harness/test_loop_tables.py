"""The closed-loop tables say what their numbers mean: an ANEES outside its 95 % band is marked
(``run``'s table, the leaderboard's Markdown, the report), and so is a chaotic row (a seed diverged:
its digits may differ on another machine)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from assocbench.harness.leaderboard import loop_markdown
from assocbench.scoring.aggregate import leaderboard_table
from assocbench.scoring.loop_summary import BAND_LEGEND, CHAOTIC_LEGEND, LOOP_COLUMNS, band_mark


def summaries(anees_by_method: dict[str, list[float]], diverged: dict[str, list[int]] | None = None) -> pd.DataFrame:
    """One closed-loop run summary per method and seed on park/hard, the band [2.289, 3.805]."""
    rows = []
    for method, values in anees_by_method.items():
        for seed, value in enumerate(values):
            row = {c: 0.0 for c in LOOP_COLUMNS}
            row.update(scenario="park/hard", method=method, seed=seed, status="ok", precision=1.0, recall=1.0, f1=1.0,
                       perfect=1.0, surprisal_gap=0.0, runtime_median_ms=0.1, proven_optimal=np.nan,
                       true_mass=np.nan, frames=100, failures=0, timed_out=0, ate_rmse=0.01, ate_smoothed=0.01,
                       anees=value, anees_lo=2.289, anees_hi=3.805,
                       diverged_at=(diverged or {}).get(method, [-1] * len(values))[seed])
            rows.append(row)
    return pd.DataFrame(rows)


def anees_cell(markdown: str, method: str) -> str:
    line = next(x for x in markdown.splitlines() if x.startswith(f"| {method} "))
    return line.split(" | ")[3]


def test_an_anees_outside_its_band_is_marked_in_the_leaderboard_markdown():
    """Reproduction: the closed-loop Markdown printed `4.18 ± 0.00 [2.29, 3.80]` with nothing
    saying the ANEES lies outside its 95 % band. Marked now (▲ above, ▼ below), with a legend."""
    md = loop_markdown(leaderboard_table(summaries({"over": [4.176], "inside": [3.0], "under": [1.5]})))
    assert anees_cell(md, "over") == "4.18 ± 0.00 [2.29, 3.81] ▲"
    assert anees_cell(md, "inside") == "3.00 ± 0.00 [2.29, 3.81]"
    assert anees_cell(md, "under") == "1.50 ± 0.00 [2.29, 3.81] ▼"
    assert BAND_LEGEND in md and BAND_LEGEND.startswith("▲ / ▼")


def test_the_band_mark_rule():
    assert band_mark(4.176, 2.289, 3.805) == "▲" and band_mark(2.0, 2.289, 3.805) == "▼"
    assert band_mark(3.805, 2.289, 3.805) == "" and band_mark(np.nan, 2.289, 3.805) == ""


def test_run_says_in_its_table_that_the_anees_is_outside_its_band(tmp_path, capsys):
    """Reproduction: `assocbench run --loop` printed `anees 33.99` beside `anees_lo 2.188` and
    `anees_hi 3.938` and nothing more (park, odometry 3x noisier than the filter is told)."""
    from assocbench.cli.main import main

    main(["run", "--scene", "park", "--loop", "--method", "mnn", "--frames", "10", "--set",
          "estimator.odometry_miscalibration=3", "--out", str(tmp_path)])
    line = next(x for x in capsys.readouterr().out.splitlines() if x.split()[:1] == ["anees"])
    assert "▲ above its 95 % band: overconfident" in line, line


def test_the_report_marks_an_anees_outside_its_band(tmp_path):
    from assocbench.harness.report import build_report

    folder = tmp_path / "loop"
    folder.mkdir()
    leaderboard_table(summaries({"over": [4.176], "inside": [3.0]})).to_csv(folder / "leaderboard.csv", index=False)
    page = next(v.decode() for k, v in build_report([folder]).items() if k != "index.html" and k.endswith(".html"))
    assert "[2.29, 3.81] ▲</td>" in page and "[2.29, 3.81]</td>" in page
    assert "▲ / ▼ beside an ANEES" in page


def method_cell(markdown: str, method: str) -> str:
    return next(x for x in markdown.splitlines() if x.startswith(f"| {method} ")).split(" | ")[0]


def test_a_row_with_a_diverged_seed_is_marked_chaotic():
    """Reproduction: on a second machine 81 of 84 planar leaderboard rows agreed to every digit; the
    3 that did not (naive16, hard, iSAM2) were runs swamped by wrong pairings, and nothing in the
    leaderboard said which rows may not reproduce. A row with a diverged seed is marked †, with the
    rule in the legend."""
    runs = summaries({"steady": [3.0, 3.1], "swamped": [3.0, 900.0]}, diverged={"swamped": [-1, 12]})
    md = loop_markdown(leaderboard_table(runs))
    assert method_cell(md, "swamped") == "| swamped †" and method_cell(md, "steady") == "| steady"
    assert CHAOTIC_LEGEND in md and "may differ on another machine" in CHAOTIC_LEGEND


def test_the_report_says_a_diverged_row_is_chaotic(tmp_path):
    from assocbench.harness.report import build_report

    folder = tmp_path / "loop"
    folder.mkdir()
    runs = summaries({"steady": [3.0], "swamped": [900.0]}, diverged={"swamped": [12]})
    leaderboard_table(runs).to_csv(folder / "leaderboard.csv", index=False)
    page = next(v.decode() for k, v in build_report([folder]).items() if k != "index.html" and k.endswith(".html"))
    badge = page[page.index('data-v="swamped"'):].split("</td>")[0]
    assert "1 diverged" in badge and "chaotic: its pairings then hinge" in badge
