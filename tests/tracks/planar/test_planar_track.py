"""The planar track through the harness: a planar scene runs from the CLI (open and closed loop),
the loop counts its closures, the new-landmark gate, suites crossed with back ends, bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from assocbench.association.problem import Problem
from assocbench.cli.main import main
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.loop import loop_records, new_landmark_features
from assocbench.harness.suite import load_suite, resolve_suite

SLAM = ["estimator.mode=slam", "estimator.target_paired=1000", "estimator.max_new_per_frame=20",
        "estimator.max_landmarks=500", "estimator.new_landmark_gate=4"]


def _loop(method: str, frames: int, seed: int = 0, extra=()) -> pd.DataFrame:
    spec = run_spec(load_run_config(None, SLAM + list(extra), method=method, scene="park", frames=frames, loop=True,
                                    seed=seed))
    return pd.DataFrame(list(loop_records(spec.source, spec.with_method(method, {}))))


def test_run_on_a_planar_scene_needs_no_other_setting(tmp_path, capsys):
    """``assocbench run --method jcbb --scene park``: the scene says its track; the open loop's
    sampled belief gives problems JCBB solves almost perfectly (measured: P 1.00, R 0.98)."""
    assert main(["run", "--method", "jcbb", "--scene", "park", "--out", str(tmp_path), "--format", "csv"]) == 0
    row = pd.read_csv(tmp_path / "summary.csv").iloc[0]
    assert row["status"] == "ok" and row["trajectory"] == "loop"
    assert row["precision"] >= 0.95 and row["recall"] >= 0.9


def test_oracle_slam_on_the_park_closes_every_loop_and_keeps_a_clean_map():
    """Two laps (500 frames, 45 posts): every revisit the truth offers is closed, no duplicate or
    false landmark is confirmed, the map is within a centimetre, and the pose NEES is finite.
    Measured, seed 0: ATE 2.7 mm, map RMSE 2.7 mm, 55 revisits closed, ANEES 3.3 (3 dof)."""
    frames = _loop("oracle", 500)
    last = frames.iloc[-1]
    assert frames["revisits"].sum() >= 40 and frames["loop_closures"].sum() == frames["revisits"].sum()
    assert last["duplicates"] == 0 and last["false_landmarks"] == 0 and last["map_size"] >= 40
    assert last["map_rmse"] < 0.01 and np.sqrt(np.mean(frames["pos_err"] ** 2)) < 0.01
    assert (frames["nees_dof"] == 3).all() and np.isfinite(frames["nees"].iloc[1:]).all()
    assert len(json.loads(last["final_map"])) == last["map_size"]


def test_a_wrong_revisit_is_not_a_loop_closure():
    """naive16 pairs far too eagerly; each closure it is credited with is a true one, so it can
    never be credited with more than the revisits there are."""
    frames = _loop("naive", 500, extra=["estimator.new_landmark_gate=0"])
    assert frames["loop_closures"].sum() <= frames["revisits"].sum()


def test_new_landmark_gate_keeps_features_near_a_landmark_from_becoming_one():
    """Feature 0 sits 3σ from the only landmark and was left unpaired; feature 1 is 10σ away.
    With the gate at 4σ only feature 1 may make a landmark; with 0 both may."""
    problem = Problem(np.array([[3.0, 0.0], [10.0, 0.0]]), np.repeat(np.eye(2)[None], 2, axis=0),
                      np.array([[0.0, 0.0]]), np.zeros((2, 2)))
    none = np.array([-1])
    assert new_landmark_features(problem, none, 4.0).tolist() == [1]
    assert new_landmark_features(problem, none, 0.0).tolist() == [0, 1]
    assert new_landmark_features(problem, np.array([1]), 4.0).tolist() == []


def test_the_planar_suite_crosses_difficulties_with_back_ends():
    suite = load_suite(resolve_suite("planar"))
    first = [cell for cell in suite.cells if (cell.scene, cell.seed) == (suite.cells[0].scene, suite.cells[0].seed)]
    assert [cell.difficulty for cell in first] == ["easy-ekf", "easy-isam2", "hard-ekf", "hard-isam2"]
    backends = [cell.cfg["estimator"]["name"] for cell in first]
    assert backends == ["ekf", "isam2", "ekf", "isam2"]


@pytest.mark.parametrize("args,needles", [
    (["--set", "lidar.beams=0"], ["lidar.beams must be an integer"]),
    (["--set", "lidar.sigma_range=-0.01"], ["lidar.sigma_range must be a finite number in [1e-06, 10]"]),
    (["--loop", "--set", "estimator.name=fastslam"], ["estimator.name must be one of ekf, isam2"]),
    (["--set", "posts.max_rms=0"], ["posts.max_rms"]),
    (["--trajectory", "circle"], ["unknown planar trajectory 'circle'"]),
])
def test_bad_planar_settings_are_one_line_errors(capsys, tmp_path, args, needles):
    code = main(["run", "--method", "jcbb", "--scene", "park", "--out", str(tmp_path / "out"), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("assocbench: error:"), err
    assert all(n in err for n in needles), err
    assert not (tmp_path / "out").exists()


def test_an_mjcf_without_posts_or_landmarks_says_both_conventions(capsys, tmp_path):
    scene = tmp_path / "empty.xml"
    scene.write_text('<mujoco><worldbody><geom type="box" size="1 1 1"/></worldbody></mujoco>')
    assert main(["run", "--method", "jcbb", "--scene", str(scene), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "cylinder geoms named lm0" in err and "site" in err


def test_isam2_on_a_camera_scene_is_refused(capsys, tmp_path):
    assert main(["run", "--method", "jcbb", "--scene", "room", "--loop", "--set", "estimator.name=isam2",
                 "--out", str(tmp_path / "o")]) == 2
    assert "is not the camera track's: its estimator is ekf" in capsys.readouterr().err


def test_frames_without_detections_are_scored_not_crashed(tmp_path):
    """The scan plane above the posts (height 2 m, posts 1 m tall): candidates but no detection in
    any frame. Each frame is scored (no pairing, nothing to recall), and the run's status says
    nothing was associated, so it cannot look good."""
    assert main(["run", "--method", "jcbb", "--scene", "park", "--frames", "5", "--set", "lidar.height=2",
                 "--out", str(tmp_path), "--format", "csv"]) == 1
    row, frames = pd.read_csv(tmp_path / "summary.csv").iloc[0], pd.read_csv(tmp_path / "frames.csv")
    assert row["status"] == "no true pair in any frame; nothing associated"
    assert (frames["n"] > 0).all() and (frames["m"] == 0).all() and (frames["tp"] + frames["fp"] == 0).all()


def test_a_scene_with_both_landmark_kinds_is_refused(capsys, tmp_path):
    scene = tmp_path / "mixed.xml"
    scene.write_text('<mujoco><worldbody><geom name="lm0" type="cylinder" size="0.1 0.5" pos="2 0 0.5"/>'
                     '<site name="lm1" pos="0 3 1"/></worldbody></mujoco>')
    assert main(["run", "--method", "jcbb", "--scene", str(scene), "--out", str(tmp_path / "o")]) == 2
    assert "camera and planar tracks: name the run's track with --track" in capsys.readouterr().err


@pytest.mark.parametrize("setting", ["lidar.sigma_range=0", "lidar.sigma_bearing_deg=0", "posts.min_points=2"])
def test_settings_that_make_a_singular_or_unchecked_fit_are_refused(capsys, tmp_path, setting):
    assert main(["run", "--method", "jcbb", "--scene", "park", "--set", setting, "--out", str(tmp_path / "o")]) == 2
    assert setting.split("=")[0] in capsys.readouterr().err
