"""A closed-loop leaderboard of a track with a top view writes its figures, the top view of each
scene drawn over the scene it was made from (the scene's path, for a user's MJCF)."""

from __future__ import annotations

from assocbench.cli.main import main


def test_a_closed_loop_planar_leaderboard_writes_a_top_view_per_scene(tmp_path):
    """It stopped with AttributeError ('list' object has no attribute 'get') after every run was
    computed: the scenes' paths were shadowed by the list of scene names."""
    suite = tmp_path / "loop.yaml"
    suite.write_text("track: planar\nbase: {loop: true, frames: 3, estimator: {mode: slam}}\n"
                     "scenes: [park, post_grid]\nmethods: [oracle, mnn]\nseeds: [0]\n")
    out = tmp_path / "out"
    assert main(["leaderboard", "--suite", str(suite), "--out", str(out), "--quiet"]) in (0, 1)
    for name in ("leaderboard_ate.png", "leaderboard_nees.png", "leaderboard_map.png", "leaderboard_map_post_grid.png"):
        assert (out / name).stat().st_size > 0, name
