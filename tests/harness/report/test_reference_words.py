"""A recorded track is scored against its data's reference association, not a truth: its leaderboard's
Markdown, its card and its report page say so; a simulated track's words are unchanged."""

from __future__ import annotations

import re

import pandas as pd
from report_inputs import tiny_leaderboard

from assocbench.harness.leaderboard import to_markdown, write_card
from assocbench.harness.report import build_report
from assocbench.tracks.base import FeatureTrack


def rows(scene: str) -> list[dict]:
    return [{"scenario": f"{scene}/{d}", "method": m, "precision": 0.5, "recall": 0.7, "f1": 0.6, "perfect": 0.0,
             "surprisal_gap": -3.0, "runtime_median_ms": 1.0, "proven_optimal": float("nan"),
             "true_mass": float("nan"), "status": "ok", "seeds": 1, "frames": 5, "failures": 0, "timed_out": 0}
            for d in ("easy", "hard") for m in ("mnn", "jcbb")]


class Recorded(FeatureTrack):
    """A feature track scored against a reference (the photos track's columns, without its data)."""

    name = "recorded_words"
    summary = "a recorded feature track"

    def columns(self, loop: bool):
        from dataclasses import replace

        return replace(super().columns(loop), scored_against="reference")


def legend(html: str) -> str:
    return html[html.index('<dl class="legend">'):html.index("</dl>")]


def test_the_markdown_says_reference_where_a_recording_is_scored_and_nothing_new_otherwise():
    metrics = ("precision", "recall", "f1", "perfect", "surprisal_gap", "runtime_median_ms", "proven_optimal", "true_mass")
    table = pd.DataFrame(rows("balbianello")).assign(**{f"{c}_std": 0.0 for c in metrics})
    truth, reference = to_markdown(table), to_markdown(table, scored_against="reference")
    assert "reference" not in truth and "each candidate's true outcome" in truth
    sentence = " Every score is against the dataset's reference association (its own labels, not ground truth)."
    assert sentence in reference and "each candidate's reference outcome" in reference
    assert reference.replace(sentence, "").replace("reference outcome", "true outcome") == truth


def test_the_report_page_of_a_recording_explains_its_columns_against_the_reference(tmp_path):
    recorded = tiny_leaderboard(tmp_path / "photos", rows("balbianello"))
    write_card(recorded, Recorded(), False)
    simulated = tiny_leaderboard(tmp_path / "camera", rows("room"))   # no card: the scene's track, camera
    files = build_report([recorded, simulated], names=["photos", "camera"])
    pages = {name: body.decode() for name, body in files.items() if name.endswith(".html") and name != "index.html"}
    words = {name: legend(page) for name, page in pages.items()}
    photos = next(w for name, w in words.items() if "recorded_words" in pages[name])
    camera = next(w for name, w in words.items() if "recorded_words" not in pages[name])
    assert "agree with the reference" in photos and "than the reference" in photos and "as the reference" in photos
    assert not re.search(r"\b(true|truth)\b", photos), photos
    assert "are true" in camera and "than the truth" in camera
