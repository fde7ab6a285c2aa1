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


def test_the_view_and_the_whole_map_track_alike(tmp_path):
    """Frame-to-model against the map rendered into the view (the default) and against every map
    point (``dense.prediction=map``, the reference): both track within a millimetre of the truth,
    and the view hands ICP at most one source point a pixel, and no more than the whole map."""
    runs = {p: run(tmp_path, p, "--method", "projective", "--scene", "crates", *FAST, "--set", f"dense.prediction={p}")
            for p in ("view", "map")}
    for code, _, summary in runs.values():
        assert code == 0 and summary.iloc[0]["status"] == "ok" and summary.iloc[0]["ate_mm"] < 1.5
    view, whole = runs["view"][1].iloc[1:], runs["map"][1].iloc[1:]
    assert (view["source_points"] <= 320 * 240).all()
    assert (view["source_points"].to_numpy() <= whole["source_points"].to_numpy()).all()
    assert (view["predict_s"] > 0).all() and (view["associate_s"] <= view["icp_s"]).all()


@pytest.mark.parametrize("args,needles", [
    (["--set", "depth.downsample=0"], ["depth.downsample"]),
    (["--set", "params.d_thr=0"], ["d_thr"]),
    (["--set", "params.angle_deg=-5"], ["angle_deg"]),
    (["--set", "fusion.d_thr=0"], ["fusion.d_thr"]),
    (["--set", "icp.max_rms=0"], ["icp.max_rms"]),
    (["--set", "dense.tracking=magic"], ["dense.tracking"]),
    (["--set", "dense.prediction=splat"], ["dense.prediction", "view, map"]),
    (["--set", "dense.index=maybe"], ["dense.index"]),
    (["--set", "dense.truth_tol=0"], ["dense.truth_tol"]),
    (["--set", "dense.path_frames=1000000000"], ["dense.path_frames", "limits.frames"]),
    (["--loop"], ["drop --loop"]),
    (["--scene", "park"], ["dense track", "scene 'park' has none"]),
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
    worse["precision"] = 1.0   # a baseline the run cannot reach at tolerance 0: check must fail, not pass
    worse.to_csv(base, index=False)
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--tolerance", "0", "--quiet"]) == 1
    worse["ate_mm"] = 0.0      # ATE may rise by ate_tolerance (5 mm) only
    worse["precision"] = 0.0
    worse.to_csv(base, index=False)
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--quiet"]) == 0
    worse.drop(columns="map_median_mm").to_csv(base, index=False)   # a guarded column missing: refused
    capsys.readouterr()
    assert main(["check", "--suite", str(suite), "--baseline", str(base), "--quiet"]) == 2
    assert "lacks columns map_median_mm" in capsys.readouterr().err
    mixed = tmp_path / "mixed.yaml"
    mixed.write_text("scenes: [crates]\nmethods: [projective, jcbb]\n")
    assert main(["leaderboard", "--suite", str(mixed), "--out", str(tmp_path / "m")]) == 2
    assert "mixes tracks" in capsys.readouterr().err


PLUGIN = '''
import os, sys, time
from dataclasses import dataclass
from assocbench.associators.dense import DenseAssociator
from assocbench.associators.dense.projective import ProjectiveAssociator

@dataclass
class Misbehaves(ProjectiveAssociator):
    """A user's dense associator that misbehaves from its third call on."""
    mode: str = "raise"
    def associate(self, points, normals, frame, R, t):
        if frame is not getattr(self, "last", None):   # ICP calls it once an iteration: count frames
            self.last, self.frames = frame, getattr(self, "frames", 0) + 1
        if self.frames > 2:
            if self.mode == "raise":
                raise RuntimeError("boom")
            if self.mode == "exit":
                sys.exit(3)
            if self.mode == "die":
                os._exit(9)
            time.sleep(60)
        return super().associate(points, normals, frame, R, t)
'''


@pytest.mark.parametrize("mode", ["raise", "exit", "die", "hang"])
def test_a_dense_plugin_that_fails_fails_only_its_own_frames(tmp_path, monkeypatch, capsys, mode):
    """A user's DenseAssociator plugs in with --method pkg.module:Class, runs in the harness's worker,
    and when it raises, exits, kills its process or hangs (past time_limit_s) only the frames it
    failed are failed: the run is reported not ok with the error, and the frames before are kept."""
    (tmp_path / "dense_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    code, frames, summary = run(tmp_path, mode, "--method", "dense_plugin:Misbehaves", "--scene", "crates", *FAST,
                                "--set", f"params.mode={mode}", "--set", "time_limit_s=3")
    assert code == 1 and summary["status"].iloc[0] != "ok"
    assert len(frames) == 6 and frames["frame"].tolist() == list(range(6))
    assert (frames["error"].fillna("") == "").iloc[:2].all()        # frame 0 (given pose) and frame 1 tracked
    assert (frames["error"].fillna("") != "").iloc[2:].any()
    assert "cannot be trusted" in capsys.readouterr().err


def test_a_run_whose_frames_cannot_be_measured_exits_1_and_fails_alone_in_a_leaderboard(tmp_path, capsys):
    """No valid pixel in the first frame (it seeds the map): the run is not ok (exit 1, the reason
    named), not a crash; in a leaderboard that run fails alone and the other difficulty is scored."""
    code, frames, summary = run(tmp_path, "dark", "--method", "projective", "--scene", "crates", *FAST,
                                "--set", "depth.min_depth=5")
    err = capsys.readouterr().err
    assert code == 1 and summary["status"].iloc[0] != "ok" and "no valid pixel" in err
    assert (frames["error"].str.contains("no valid pixel")).all()
    suite = tmp_path / "dark.yaml"
    suite.write_text("base: {frames: 4, resolution: [320, 240], depth: {downsample: 1}}\nscenes: [crates]\n"
                     "methods: [projective]\nseeds: [0]\ndifficulties: {dark: {depth: {min_depth: 5}}, lit: {}}\n")
    out = tmp_path / "board"
    assert main(["leaderboard", "--suite", str(suite), "--out", str(out), "--quiet"]) == 1
    table = pd.read_csv(out / "leaderboard.csv").set_index("difficulty")
    assert table.loc["lit", "status"] == "ok" and table.loc["dark", "status"] != "ok"


def test_frame_to_frame_after_a_lost_frame_registers_to_the_last_tracked_frame():
    """A lost frame's pose is unknown (ICP failed; the pose is held), so frame-to-frame tracking
    registers the next frame to the last tracked frame's points, not to the lost frame's points
    placed at the held pose, one step off: on bays seed 1 (40 frames) every pose after the lost
    frame 8 inherited its 57 mm step (ATE 61.5 mm, all later steps right)."""
    from assocbench.associators.dense import make_dense_associator
    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.harness.runner import GuardedCalls
    from assocbench.tracks.dense.run import dense_records
    from assocbench.tracks.dense.sequence import load_dense_sequence

    cfg = load_run_config(None, ["resolution=[320,240]", "depth.downsample=1", "dense.tracking=frame"],
                          method="projective", scene="crates", frames=5)
    spec = run_spec(cfg)
    seq = load_dense_sequence(spec.source.spec)
    calls = GuardedCalls(spec.time_limit_s, {2: ("lost on purpose", 0.0)}, lambda k, limit: None)
    recs = list(dense_records(seq, spec, calls, lambda: make_dense_associator("projective")))
    valid = [int(seq.frame(k).valid.sum()) for k in range(3)]
    assert valid[1] != valid[2]                       # the two candidate sources can be told apart
    assert recs[2]["icp_failed"] and not recs[3]["icp_failed"]
    assert recs[3]["source_points"] == valid[1] and recs[4]["source_points"] == int(seq.frame(3).valid.sum())


def test_fusion_columns_are_empty_exactly_on_the_frames_not_fused():
    """``frames.csv``'s fusion columns (``fusion_considered``: map points on a valid pixel) are empty
    on a frame not fused (its ICP or its method failed) and only there: frame 0, fused into the
    empty map, had them empty too, so it read as a frame not fused (the cold check found)."""
    from assocbench.associators.dense import make_dense_associator
    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.harness.runner import GuardedCalls
    from assocbench.tracks.dense.run import dense_records
    from assocbench.tracks.dense.sequence import load_dense_sequence

    cfg = load_run_config(None, ["resolution=[320,240]", "depth.downsample=1"], method="projective",
                          scene="crates", frames=4)
    spec = run_spec(cfg)
    seq = load_dense_sequence(spec.source.spec)
    calls = GuardedCalls(spec.time_limit_s, {2: ("failed on purpose", 0.0)}, lambda k, limit: None)
    recs = pd.DataFrame(list(dense_records(seq, spec, calls, lambda: make_dense_associator("projective"))))
    fused = ~recs["icp_failed"].astype(bool)
    assert fused.tolist() == [True, True, False, True]
    assert recs.loc[fused, "fusion_considered"].notna().all() and recs.loc[~fused, "fusion_considered"].isna().all()
    first = recs.iloc[0]
    assert first["fusion_considered"] == 0 and first["merged"] == 0 and first["added"] == first["map_points"] > 0
    assert recs.loc[1, "fusion_considered"] > 0

def test_the_run_end_picture_and_map_file_do_not_depend_on_the_rows_spatial_order(tmp_path):
    """The leaderboard's subsample (``final_map``) and ``map.npz`` list the points in the order
    they were added: a map sorted after every frame and one never sorted give the same bytes."""
    from types import SimpleNamespace

    import dense_world as dw

    from assocbench.tracks.dense.fusion import PointMap, fuse
    from assocbench.tracks.dense.run import PICTURE_POINTS, run_end
    from assocbench.tracks.dense.settings import FusionConfig

    scene = tmp_path / "world.xml"
    scene.write_text(dw.WORLD_XML.replace("</worldbody>", '<site name="lm0" pos="2.6 0 1.5"/></worldbody>'))
    _, _, frames = dw.sequence(6, yaw_per_frame=6.0)
    seq = type("Seq", (), {"K": dw.K320, "__len__": lambda self: len(frames)})()   # what run_end reads of one
    spec = SimpleNamespace(source=SimpleNamespace(spec=SimpleNamespace(scene=str(scene))))
    ends = []
    for share in (None, 0.0):
        pmap, cfg = PointMap(), FusionConfig(dormant_frames=2)
        pmap.sort_share = share
        for k, f in enumerate(frames):
            fuse(pmap, f, f.R, f.t, k, cfg)
        assert len(pmap) > PICTURE_POINTS   # a subsample, not the whole map
        out = tmp_path / f"share{share}"
        out.mkdir()
        ends.append((run_end(seq, spec, pmap, out), np.load(out / "map.npz"), pmap.born.copy()))
    (plain, plain_npz, plain_born), (sorted_, sorted_npz, sorted_born) = ends
    assert not np.array_equal(plain_born, sorted_born)   # the rows' orders differ
    assert plain["final_map"] == sorted_["final_map"]
    for name in ("positions", "normals", "weights", "error_mm"):
        np.testing.assert_array_equal(plain_npz[name], sorted_npz[name], err_msg=name)
