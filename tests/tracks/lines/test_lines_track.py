"""The lines track through the harness: a lines scene runs from the CLI (open and closed loop), the
sequence is reproducible, extraction quality on a shipped scene, the top view, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from assocbench.cli.main import main
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.loop import loop_records
from assocbench.tracks.lines.metrics import extraction_scores
from assocbench.tracks.lines.plots import segment_status
from assocbench.tracks.lines.sequence import LineSequenceSpec, make_line_sequence
from assocbench.tracks.lines.settings import LineExtractorConfig


def _summary(tmp_path, *args) -> pd.Series:
    assert main(["run", *args, "--out", str(tmp_path), "--format", "csv"]) == 0
    return pd.read_csv(tmp_path / "summary.csv").iloc[0]


def test_run_on_a_lines_scene_needs_no_other_setting(tmp_path):
    """``assocbench run --method jcbb --scene office``: the scene says its track (lw* walls); the
    open loop's sampled belief gives problems JCBB solves well (measured, 40 frames: P 0.995, R 0.95)."""
    row = _summary(tmp_path, "--method", "jcbb", "--scene", "office")
    assert row["status"] == "ok" and row["trajectory"] == "loop"
    assert row["precision"] >= 0.95 and row["recall"] >= 0.9


def test_closed_loop_oracle_localises_to_centimetres_and_records_the_last_scan(tmp_path):
    """EKF localisation with the true association on the hallway: the pose stays within 2 cm
    (measured, 150 frames: ATE 1.3 mm) and the last frame's snapshot is recorded for the top view."""
    spec = run_spec(load_run_config(None, [], method="oracle", scene="hallway", frames=150, loop=True))
    frames = pd.DataFrame(list(loop_records(spec.source, spec.with_method("oracle", {}))))
    assert np.sqrt(np.mean(frames["pos_err"] ** 2)) < 0.02
    assert (frames["nees_dof"] == 3).all() and (frames["fp"] == 0).all()
    snap = json.loads(frames["final_scan"].dropna().iloc[-1])
    assert len(snap["segments"]) == len(snap["status"]) > 0 and len(snap["points"]) > 100
    assert "wrong" not in snap["status"]


def test_same_seed_same_sequence_bit_for_bit():
    spec = LineSequenceSpec(scene="office", frames=15, seed=3, lines=LineExtractorConfig(method="ransac"))
    a, b = make_line_sequence(spec), make_line_sequence(spec)
    for k in range(15):
        assert np.array_equal(a.z[k], b.z[k]) and np.array_equal(a.R[k], b.R[k])
        assert np.array_equal(a.labels[k], b.labels[k])


@pytest.mark.parametrize("method,recall", [("split_merge", 0.95), ("ransac", 0.95), ("polar", 0.0)])
def test_extraction_finds_the_office_walls(method, recall):
    """Share of truly extractable map lines found, 60 frames of the office (measured: split-and-merge
    0.99, RANSAC 0.99, polar 0.10: the breakpoint baseline loses every wall that meets another at a
    corner). On-wall lines fit within a few tenths of a degree and centimetres (measured: α 0.12–0.18°,
    r 8–9 mm RMS)."""
    s = extraction_scores(make_line_sequence(LineSequenceSpec(scene="office", frames=60,
                                                              lines=LineExtractorConfig(method=method))))
    assert s["recall"] >= recall
    assert s["alpha_rms_deg"] < 1.0 and s["r_rms_mm"] < 30


def test_a_second_piece_of_a_paired_wall_is_not_missed():
    """Features 0 and 1 both lie on map line 7 (a wall split by a doorway), feature 2 on line 4,
    feature 3 is clutter. Line 7 paired with feature 0 and line 4 with the clutter: the second
    piece of line 7 is right (its line was updated), line 4's own piece missed, the clutter wrong."""
    status = segment_status(np.array([7, 7, 4, -1]), np.array([7, 4]), np.array([0, 3]), 4)
    assert status == ["right", "right", "missed", "wrong"]
    status = segment_status(np.array([7, 7, 4, -1]), np.array([7, 4]), np.array([0, 2]), 4)
    assert status == ["right", "right", "right", "clutter"]


def test_a_scan_that_sees_nothing_is_not_a_good_run(tmp_path):
    """lidar.max_range 0.3 m: no beam returns, no line is extracted; the run completes and its
    status says the numbers cannot be trusted and the exit code is 1, not 0."""
    args = ["run", "--method", "jcbb", "--scene", "office", "--set", "lidar.max_range=0.3", "--frames", "5"]
    assert main(args + ["--out", str(tmp_path), "--format", "csv"]) == 1
    assert pd.read_csv(tmp_path / "summary.csv").iloc[0]["status"] == "no candidates in any frame"


def test_dropped_returns_are_skipped(tmp_path):
    """Half the beams return NaN: lines are still extracted and paired."""
    row = _summary(tmp_path, "--method", "jcbb", "--scene", "office", "--set", "lidar.dropout=0.5", "--frames", "10")
    assert row["recall"] > 0.5


@pytest.mark.parametrize("sets,message", [
    (["estimator.mode=slam"], "localisation"),
    (["estimator.name=isam2"], "ekf"),
    (["lidar.mode=geometric"], "lidar.mode"),
    (["lines.min_points=2"], "min_points"),
    (["lines.method=hough"], "method"),
])
def test_bad_settings_are_one_line_errors(tmp_path, capsys, sets, message):
    args = ["run", "--method", "jcbb", "--scene", "office", "--loop", "--out", str(tmp_path)]
    assert main(args + [a for s in sets for a in ("--set", s)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err


def test_zero_length_wall_in_a_user_mjcf_is_a_one_line_error(tmp_path, capsys):
    path = tmp_path / "room.xml"
    path.write_text('<mujoco><worldbody><geom name="floor" type="plane" size="9 9 0.1"/>'
                    '<geom name="lw0" type="box" pos="0 3 0.6" size="0 0.05 0.6"/></worldbody></mujoco>')
    assert main(["run", "--method", "jcbb", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and ("lw0" in err or "size" in err)


def test_extracted_line_covariance_describes_its_error_on_a_shipped_scene():
    """Over 100 office frames the NEES of on-wall lines against their true line is 2 (χ²₂) when
    every beam hit the wall (measured 1.85), and stays below 3 with the default 80 % share, whose
    few contaminated lines make a tail (measured 2.14)."""
    seq = make_line_sequence(LineSequenceSpec(scene="office", frames=100, lines=LineExtractorConfig(min_share=0.999)))
    assert extraction_scores(seq)["nees"] == pytest.approx(2.0, abs=0.3)
    seq = make_line_sequence(LineSequenceSpec(scene="office", frames=100))
    assert extraction_scores(seq)["nees"] < 3.0


def test_a_wall_above_the_scan_plane_is_a_one_line_error(tmp_path, capsys):
    """A map wall from z 2.3 to 2.7 m is a candidate the lidar at 0.5 m can never measure."""
    path = tmp_path / "short.xml"
    path.write_text('<mujoco><worldbody><geom name="floor" type="plane" size="9 9 0.1"/>'
                    '<geom name="lw0" type="box" pos="0 3 2.5" size="3 0.05 0.2"/>'
                    '<geom name="lw1" type="box" pos="0 -3 0.6" size="3 0.05 0.6"/></worldbody></mujoco>')
    assert main(["run", "--method", "jcbb", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "lw0" in err and "scan plane" in err
    assert not (tmp_path / "o").exists()


def test_a_run_with_nothing_to_associate_never_reads_as_perfect(tmp_path):
    """95 % of the beams drop out: no line is extracted while walls stay candidates. The empty answer
    is exact in every frame, yet perfect, jc_share and surprisal_gap are NaN, not 1 and 0."""
    args = ["run", "--method", "jcbb", "--scene", "office", "--frames", "10", "--set", "lidar.dropout=0.95"]
    assert main(args + ["--out", str(tmp_path), "--format", "csv"]) == 1
    row = pd.read_csv(tmp_path / "summary.csv").iloc[0]
    assert row["status"] == "no true pair in any frame; nothing associated"
    assert np.isnan(row["perfect"]) and np.isnan(row["jc_share"]) and np.isnan(row["surprisal_gap"])
