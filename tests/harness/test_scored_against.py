"""What a recorded track adds to the core: its scores are against a reference (the leaderboard's
card, Markdown and figures say so), and summary columns of its own computed from a whole run."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd

from assocbench.harness import leaderboard
from assocbench.harness.runner import summarize_run
from assocbench.scoring.aggregate import leaderboard_table
from assocbench.tracks.base import FeatureTrack
from assocbench.viz.loop_plots import map_figure


class Recorded(FeatureTrack):
    """A feature track scored against a reference, with one run score of its own."""

    name = "recorded_fake"

    def columns(self, loop: bool):
        cols = super().columns(loop)
        return replace(cols, summary=cols.summary + ("sightings",), scored_against="reference")

    def run_scores(self, frames) -> dict:
        return {"sightings": int(frames["m"].sum())}


def loop_summaries() -> pd.DataFrame:
    rows = []
    for method, ate in (("oracle", 0.5), ("jcbb", 1.0)):
        rows.append({"scenario": "log/recorded", "scene": "log", "difficulty": "recorded", "method": method, "seed": 0,
                     "status": "ok", "precision": 1.0, "recall": 1.0, "f1": 1.0, "perfect": 1.0, "surprisal_gap": 0.0,
                     "runtime_median_ms": 0.1, "frames": 10, "failures": 0, "timed_out": 0, "ate_rmse": ate,
                     "ate_smoothed": ate, "rot_rmse_deg": 1.0, "anees": 3.0, "anees_lo": 2.5, "anees_hi": 3.5,
                     "diverged_at": -1, "map_size": 5, "duplicates": 0, "false_landmarks": 0, "map_rmse": 0.1,
                     "new_landmarks": 5, "no_depth": 0, "sightings": 20 if method == "jcbb" else 24})
    return pd.DataFrame(rows)


def test_a_run_gets_the_tracks_own_scores_beside_the_shared_ones():
    frames = pd.DataFrame({"frame": [0, 1], "n": [2, 2], "m": [3, 4], "tp": [2, 1], "fp": [0, 1], "fn": [0, 0],
                           "perfect": [True, False], "surprisal": [1.0, 2.0], "surprisal_true": [1.0, 1.5],
                           "jointly_compatible": [True, True], "clutter_accepted": [0, 0], "runtime_s": [1e-4, 2e-4],
                           "error": ["", ""]})
    summary = summarize_run(Recorded(), frames)
    assert summary["sightings"] == 7 and summary["precision"] == 0.75


def test_the_leaderboard_keeps_a_tracks_own_columns_and_says_reference(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.setattr("assocbench.harness.leaderboard.plot_precision_recall", lambda *a: None)
    monkeypatch.setattr("assocbench.harness.leaderboard.plot_runtime", lambda *a: None)
    monkeypatch.setattr("assocbench.harness.leaderboard.write_loop_plots", lambda *a: {})
    table = leaderboard_table(loop_summaries(), ["sightings"])
    assert list(table["sightings"]) == [24, 20] and "sightings_std" in table
    paths = leaderboard.write_leaderboard(loop_summaries(), pd.DataFrame(), tmp_path, Recorded())
    text = paths["md"].read_text()
    assert "**oracle (reference)**" in text and "oracle (truth)" not in text and "true association" not in text
    assert "| sightings |" in text.replace("sightings | diverged", "sightings |")
    card = leaderboard.card(Recorded(), True)
    assert card["scored_against"] == "reference"
    assert json.loads(leaderboard.write_card(tmp_path, Recorded(), True).read_text())["scored_against"] == "reference"
    plt.close("all")


def test_a_simulated_tracks_leaderboard_still_says_truth():
    text = leaderboard.loop_markdown(leaderboard_table(loop_summaries()))
    assert "**oracle (truth)** is the true association" in text and "reference association" not in text


def test_the_top_view_names_the_reference_path_and_landmarks():
    frames = pd.DataFrame({"method": ["jcbb"] * 2, "frame": [0, 1], "true_x": [0.0, 1.0], "true_y": [0.0, 0.0],
                           "est_x": [0.0, 1.1], "est_y": [0.0, 0.1]})
    fig = map_figure(frames, np.array([[0.5, 1.0]]), title="t", scored_against="reference")
    caption = " ".join(t.get_text() for t in fig.texts)
    assert "reference path" in caption and "reference landmarks" in caption and "true" not in caption
