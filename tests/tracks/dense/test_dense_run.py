"""The dense track end to end: `assocbench run --method projective|kdtree` on a real render, its
files, its reproducibility, and bad input refused in one line with exit code 2."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from assocbench.cli.main import main
from assocbench.sim.ply import read_ply

FAST = ["--frames", "6", "--set", "resolution=[320,240]", "--set", "depth.downsample=1"]


def run(tmp_path, name: str, *extra: str) -> tuple[int, pd.DataFrame, pd.DataFrame]:
    out = tmp_path / name
    code = main(["run", *extra, "--out", str(out), "--format", "csv"])
    return code, pd.read_csv(out / "frames.csv"), pd.read_csv(out / "summary.csv")


@pytest.mark.parametrize("method", ["projective", "kdtree"])
def test_a_short_run_tracks_fuses_and_writes_every_file(tmp_path, method):
    code, frames, summary = run(tmp_path, method, "--method", method, "--scene", "crates", *FAST,
                                "--set", "dense.tracking=truth")
    row = summary.iloc[0]
    assert code == 0 and row["status"] == "ok"
    assert row["precision"] > 0.9 and row["recall"] > 0.5          # pairs at the previous true pose, truth-fused map
    assert row["map_median_mm"] < 10 and row["map_points"] > 10_000
    assert frames["step_error_mm"].iloc[1:].max() < 20              # one ICP step from the previous true pose
    ply = read_ply(tmp_path / method / "map.ply")
    assert len(ply["x"]) == row["map_points"] and np.isfinite(ply["error_mm"]).all()
    for name in ("truth.txt", "estimate.txt", "map.png"):
        assert (tmp_path / method / name).stat().st_size > 0


def test_same_seed_same_numbers_except_time(tmp_path):
    a = run(tmp_path, "a", "--method", "projective", "--scene", "crates", *FAST)[2]
    b = run(tmp_path, "b", "--method", "projective", "--scene", "crates", *FAST)[2]
    timing = ["icp_ms", "fusion_ms", "fps"]
    pd.testing.assert_frame_equal(a.drop(columns=timing), b.drop(columns=timing))


@pytest.mark.parametrize("args,needles", [
    (["--set", "depth.downsample=0"], ["depth.downsample"]),
    (["--set", "depth.max_depth=0.01", "--set", "depth.min_depth=0.005"], ["first depth frame", "no valid pixel"]),
    (["--set", "params.d_thr=0"], ["d_thr"]),
    (["--set", "params.angle_deg=-5"], ["angle_deg"]),
    (["--set", "fusion.d_thr=0"], ["fusion.d_thr"]),
    (["--set", "icp.max_rms=0"], ["icp.max_rms"]),
    (["--set", "dense.tracking=magic"], ["dense.tracking"]),
    (["--set", "dense.truth_tol=0"], ["dense.truth_tol"]),
    (["--set", "dense.path_frames=1000000000"], ["dense.path_frames", "limits.frames"]),
    (["--loop"], ["drop --loop"]),
    (["--scene", "park"], ["dense track", "camera scene"]),
])
def test_bad_dense_settings_are_one_line_errors(tmp_path, capsys, args, needles):
    code = main(["run", "--method", "projective", "--scene", "crates", "--frames", "3", "--set", "resolution=[320,240]",
                 *args, "--out", str(tmp_path / "bad")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    assert not (tmp_path / "bad" / "summary.csv").exists()


def test_a_dense_suite_gives_a_leaderboard_and_a_check_that_guards_it(tmp_path, capsys):
    suite = tmp_path / "tiny_dense.yaml"
    suite.write_text("base: {frames: 4, resolution: [320, 240], depth: {downsample: 1}, dense: {tracking: truth}}\n"
                     "scenes: [crates]\nmethods: [projective]\nseeds: [0]\n")
    out = tmp_path / "board"
    assert main(["leaderboard", "--suite", str(suite), "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "leaderboard.csv")
    assert list(table["method"]) == ["projective"] and table["status"].iloc[0] == "ok"
    assert "## crates/default" in (out / "leaderboard.md").read_text()
    assert (out / "leaderboard_map.png").stat().st_size > 0
    base = tmp_path / "baseline.csv"
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--update", "--quiet"]) == 0
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--quiet"]) == 0
    worse = pd.read_csv(base)
    worse["precision"] = 1.5   # a baseline the run cannot reach: check must fail, not pass
    worse.to_csv(base, index=False)
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--quiet"]) == 1
    mixed = tmp_path / "mixed.yaml"
    mixed.write_text("scenes: [crates]\nmethods: [projective, jcbb]\n")
    capsys.readouterr()
    assert main(["leaderboard", "--suite", str(mixed), "--out", str(tmp_path / "m")]) == 2
    assert "mixes dense methods" in capsys.readouterr().err
