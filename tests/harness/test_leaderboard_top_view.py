"""The closed-loop leaderboard's top view is drawn from the scene each scenario was made from."""

from __future__ import annotations

import matplotlib.pyplot as plt
import pandas as pd

from assocbench.harness import leaderboard
from assocbench.tracks.base import FeatureTrack


class TopViewTrack(FeatureTrack):
    """A track with a top view that remembers which scene path it was asked to draw."""

    name = "fake"

    def __init__(self) -> None:
        self.paths: list[str] = []

    def map_figure(self, frames, scene: str, title: str):
        self.paths.append(scene)
        return plt.figure()


def test_top_view_gets_the_scene_path_of_each_scenario(tmp_path, monkeypatch):
    monkeypatch.setattr("assocbench.viz.loop_plots.ate_figure", lambda *a: plt.figure())
    monkeypatch.setattr("assocbench.viz.loop_plots.nees_figure", lambda *a: plt.figure())
    table = pd.DataFrame({"scenario": ["park/hard", "grid/hard"], "method": ["jcbb", "jcbb"]})
    frames = pd.DataFrame({"scenario": ["park/hard", "grid/hard"], "seed": [0, 0], "frame": [0, 0]})
    track = TopViewTrack()
    paths = leaderboard.write_loop_plots(table, frames, tmp_path, ["hard"], track,
                                         {"park": "/data/park.xml", "grid": "/data/grid.xml"})
    assert sorted(track.paths) == ["/data/grid.xml", "/data/park.xml"]
    assert paths["map"].is_file() and paths["map_park"].is_file()
