"""The recorded range-bearing track (planar_log): a user's log written from the documented format
runs end to end, open and closed loop on both back ends; the shipped example does; the reference
solution recovers a simulated log's path; frames without a sighting are composed away; the track
is unavailable without gtsam; scores are against the reference."""

from __future__ import annotations

import importlib.util
import pickle
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cli.test_cli import assert_one_line_error

from assocbench.cli.main import main
from assocbench.models.se2 import between, compose
from assocbench.sources.range_bearing_log import read_log

pytestmark = pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the planar_log track needs gtsam")
ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "examples" / "planar_log" / "square.log"
LANDMARKS = np.array([[3.0, 2.0], [6.0, -2.0], [9.0, 2.5], [12.0, -1.5], [15.0, 2.0]])


def simulated_log(path: Path, seed: int = 3) -> np.ndarray:
    """Write a log in the documented format: 31 poses out along a line and back, sightings of the
    landmarks within 6 m ahead (ids 50..54) and one without a reference id; returns the true poses.
    Every other pose sees nothing (frames are only the poses with a sighting)."""
    rng = np.random.default_rng(seed)
    out = [(0.5 * k, 0.0, 0.0) for k in range(31)] + [(15.0 - 0.5 * k, 0.3, np.pi) for k in range(1, 31)]
    poses = np.array(out)
    lines = ["# a simulated log"]
    for k, pose in enumerate(poses):
        if k:
            d = between(poses[k - 1], pose) + rng.normal(0, [0.01, 0.005, 0.002])
            lines.append(f"ODOMETRY {k - 1} {k} {d[0]:.6f} {d[1]:.6f} {d[2]:.6f} 1e-4 0 0 2.5e-5 0 4e-6")
        if k % 2:
            continue
        c, s = np.cos(pose[2]), np.sin(pose[2])
        for j, (x, y) in enumerate((LANDMARKS - pose[:2]) @ np.array([[c, -s], [s, c]])):
            if 0.5 < x < 6.0:
                x, y = np.array([x, y]) + rng.normal(0, 0.05, 2)
                lines.append(f"LANDMARK {k} {50 + j} {x:.5f} {y:.5f} 0.0025 0.0 0.0025")
        if k == 20:
            lines.append(f"LANDMARK {k} - 2.0 1.0 0.0025 0.0 0.0025")
    path.write_text("\n".join(lines) + "\n")
    return poses


def run_csv(capsys, tmp_path, *args: str) -> pd.Series:
    out = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
    code = main(["run", "--track", "planar_log", "--method", "jcbb", "--format", "csv", "--out", str(out), *args])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return pd.read_csv(out / "summary.csv").iloc[0]


def test_a_users_log_runs_end_to_end_open_and_closed_loop_on_both_back_ends(capsys, tmp_path):
    path = tmp_path / "mine.log"
    simulated_log(path)
    sightings = read_log(path).sighting_pose
    open_loop = run_csv(capsys, tmp_path, "--scene", str(path))
    assert open_loop["status"] == "ok" and open_loop["frames"] == len(np.unique(sightings))
    assert open_loop["precision"] == 1.0 and open_loop["recall"] > 0.95   # a 3.5σ draw leaves one unpaired
    for backend in ("ekf", "isam2"):
        loop = run_csv(capsys, tmp_path, "--scene", str(path), "--loop", "--set", "estimator.mode=slam",
                       "--set", f"estimator.name={backend}")
        assert loop["status"] == "ok" and loop["ate_rmse"] < 0.2, loop
        assert loop["pair_precision"] == 1.0 and loop["reference_landmarks"] == len(LANDMARKS)
        assert loop["map_size"] == len(LANDMARKS) and loop["duplicates"] == 0


def test_the_shipped_example_runs_end_to_end(capsys, tmp_path):
    assert run_csv(capsys, tmp_path, "--scene", str(EXAMPLE))["status"] == "ok"
    loop = run_csv(capsys, tmp_path, "--scene", str(EXAMPLE), "--loop", "--set", "estimator.mode=slam")
    assert loop["status"] == "ok" and loop["pair_precision"] == 1.0 and loop["reference_landmarks"] == 8


def test_the_reference_solution_recovers_a_simulated_path_and_is_cached(tmp_path, monkeypatch, capsys):
    from assocbench.tracks.planar_log import reference

    path = tmp_path / "mine.log"
    truth = simulated_log(path)
    log = read_log(path)
    solution = reference.reference_solution(log, tmp_path / "cache")
    assert f"reference solution of mine: {solution.describe()}" in capsys.readouterr().err   # its fit, said once
    assert np.sqrt(np.mean(np.sum((solution.poses[:, :2] - truth[:, :2]) ** 2, axis=1))) < 0.1
    assert np.abs(solution.landmarks - LANDMARKS[solution.ids - 50]).max() < 0.1
    assert 0.3 < solution.chi2_dof < 3 and solution.sightings == np.sum(log.sighting_ref >= 0)
    monkeypatch.setattr(reference, "solve", lambda log: pytest.fail("solved again instead of read from the cache"))
    reference._SOLVED.clear()
    again = reference.reference_solution(log, tmp_path / "cache")
    assert np.array_equal(again.poses, solution.poses)


def test_poses_without_a_sighting_are_composed_into_one_motion(tmp_path):
    from assocbench.tracks.planar_log.sequence import make_log_sequence
    from assocbench.tracks.planar_log.settings import LogConfig

    path = tmp_path / "mine.log"
    simulated_log(path)
    log = read_log(path)

    class Reference:   # the sequence reads only these
        poses = np.zeros((len(log.pose_ids), 3))
        ids, landmarks = np.arange(50, 55), LANDMARKS

        def index_of(self, refs):
            return np.where(refs >= 0, refs - 50, -1)

        def describe(self):
            return ""

    seq = make_log_sequence(log, Reference(), LogConfig(odometry_scale=2.0))
    assert list(seq.pose_index) == sorted(set(log.sighting_pose.tolist()))
    end = np.zeros(3)
    for inc in log.increments[:seq.pose_index[-1]]:
        end = compose(end, inc)
    chained = np.zeros(3)
    for inc in seq.increments[1:]:
        chained = compose(chained, inc)
    assert np.allclose(chained, end)
    one_step = np.diag([1e-4, 2.5e-5, 4e-6])
    assert np.trace(seq.motion_covariances[1]) > 2.0 * np.trace(one_step)   # two steps, doubled


def test_the_source_is_keyed_by_file_and_settings_and_pickles_light(tmp_path):
    from assocbench.harness.config import load_run_config, run_spec

    path = tmp_path / "mine.log"
    simulated_log(path)
    spec = run_spec(load_run_config(track="planar_log", scene=str(path), method="jcbb"))
    source = spec.source
    assert len(source) == len(np.unique(read_log(path).sighting_pose))
    source.load(tmp_path / "cache")
    assert len(pickle.dumps(source)) < 2000
    other = run_spec(load_run_config(track="planar_log", scene=str(path), method="jcbb",
                                     sets=["log.odometry_scale=2"])).source
    assert other.key != source.key
    path.write_text(path.read_text() + "# edited\n")
    assert run_spec(load_run_config(track="planar_log", scene=str(path), method="jcbb")).source.key != source.key


def test_without_gtsam_the_track_is_unavailable_and_a_run_is_refused(capsys, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "gtsam" else real(name, *a))
    assert main(["list"]) == 0
    listed = capsys.readouterr().out
    assert "planar_log" in listed and "unavailable here: gtsam is not installed (pip install 'assocbench[gtsam]'" \
        in listed
    assert_one_line_error(capsys, main(["run", "--track", "planar_log", "--method", "jcbb"]),
                          "planar_log track is unavailable here", "assocbench[gtsam]")


def test_its_scores_are_against_the_reference():
    from assocbench.harness.leaderboard import card
    from assocbench.tracks.registry import get_track

    track = get_track("planar_log")
    assert card(track, True)["scored_against"] == "reference" and card(track, False)["scored_against"] == "reference"
    assert {"pair_precision", "pair_recall", "reference_landmarks"} <= set(track.columns(True).summary)


def test_a_log_whose_odometry_covariance_is_right_needs_no_scale(tmp_path):
    """White odometry noise drawn from the covariance the log states: its dead reckoning's NEES over
    windows of any length averages 3, so the consistent scale is 1 (the reference is the truth here)."""
    from assocbench.tracks.planar_log.consistency import consistent_scale

    rng = np.random.default_rng(5)
    Q = np.diag([1e-3, 5e-4, 2e-4])
    truth, lines = [np.zeros(3)], []
    for k in range(1, 2001):
        d = np.array([0.5, 0.0, 0.01 * np.sin(k / 50)])
        truth.append(compose(truth[-1], d))
        d = d + rng.multivariate_normal(np.zeros(3), Q)
        lines.append(f"ODOMETRY {k - 1} {k} {d[0]:.8f} {d[1]:.8f} {d[2]:.8f} 1e-3 0 0 5e-4 0 2e-4")
    path = tmp_path / "white.log"
    path.write_text("\n".join(lines) + "\n")
    for window in (1, 10, 50):
        assert 0.75 < consistent_scale(read_log(path), np.array(truth), window) < 1.3
