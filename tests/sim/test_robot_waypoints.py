"""A robot's waypoint path in the plane (``sim.robot_waypoints``): where each frame is, which way
it faces, the YAML form with headings and times, and the clearance check's messages."""

from __future__ import annotations

import numpy as np
import pytest
from user_room import path_csv, room_mjcf

from assocbench.errors import UserError
from assocbench.models.range_bearing import wrap
from assocbench.sim.planar_scene import load_planar_scene
from assocbench.sim.planar_trajectory import planar_trajectory
from assocbench.sim.robot_waypoints import TURN, read_robot_waypoints, waypoint_poses


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("room")
    return load_planar_scene(room_mjcf(folder, "planar")), folder


def test_equal_steps_through_every_waypoint_facing_along_the_legs(room):
    """An L of legs 6 m (+x) and 4 m (+y) in 11 frames: 1 m a frame, frames 0, 6, 10 on the
    waypoints; the heading is the leg's away from the corner and turns over ±TURN around it."""
    scene, folder = room
    file = path_csv(folder, [(1.5, 1.2), (7.5, 1.2), (7.5, 5.2)], "l.csv")
    poses = waypoint_poses(read_robot_waypoints(file), 11)
    assert np.allclose(np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1), 1.0)
    assert np.allclose(poses[[0, 6, 10], :2], [[1.5, 1.2], [7.5, 1.2], [7.5, 5.2]])
    assert np.allclose(poses[:6, 2], 0.0) and np.allclose(poses[7:, 2], np.pi / 2)
    assert np.isclose(poses[6, 2], np.pi / 4)                 # half way through the turn at the corner
    fine = waypoint_poses(read_robot_waypoints(file), 1001)   # 1 cm a frame: the turn spans 2 TURN
    turning = np.flatnonzero((fine[:, 2] > 1e-9) & (fine[:, 2] < np.pi / 2 - 1e-9))
    assert np.isclose((turning[-1] - turning[0] + 2) * 0.01, 2 * TURN, atol=0.011)
    with pytest.raises(UserError, match="trajectory 'waypoints' takes no parameter 'laps'"):
        planar_trajectory(scene, "waypoints", 5, file=str(file), laps=2)


def test_yaml_headings_and_times(room, tmp_path):
    """Given headings are interpolated the shorter way round (170° to −170° passes 180°); times
    set the speed of each leg (2 m in 1 s, then 2 m in 3 s)."""
    file = tmp_path / "walk.yaml"
    file.write_text("waypoints:\n  - {position: [1.5, 1.2], heading: 170, t: 0}\n"
                    "  - {position: [3.5, 1.2], heading: -170, t: 1}\n  - {position: [5.5, 1.2], heading: -170, t: 4}\n")
    poses = waypoint_poses(read_robot_waypoints(file), 5)      # t = 0, 1, 2, 3, 4
    assert np.allclose(poses[:, 0], [1.5, 3.5, 3.5 + 2 / 3, 3.5 + 4 / 3, 5.5])
    assert np.isclose(abs(wrap(poses[0, 2] - np.deg2rad(170))), 0) and np.isclose(poses[1, 2], np.deg2rad(-170))
    half = waypoint_poses(read_robot_waypoints(file), 9)[1]   # t = 0.5: half way along the first leg
    assert np.isclose(abs(half[2]), np.pi)


@pytest.mark.parametrize("text,message", [
    ("x,y,heading\n1.5,1.2,0\n3.5,1.2,\n", "heading = '' is not a number"),
    ("- {position: [1.5, 1.2], heading: 0}\n- {position: [3.5, 1.2]}\n", "give heading for every waypoint or for none"),
    ("- {position: [1.5, 1.2], t: 1}\n- {position: [3.5, 1.2], t: 1}\n", "t must increase strictly (1 then 1)"),
    ("- {position: [1.5, 1.2], yaw: 0}\n- {position: [3.5, 1.2]}\n", "expected a mapping with position: [x, y]"),
])
def test_ill_formed_rows_are_one_line_errors(tmp_path, text, message):
    file = tmp_path / ("w.csv" if text.startswith("x") else "w.yaml")
    file.write_text(text)
    with pytest.raises(UserError) as err:
        read_robot_waypoints(file)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_spreadsheets_csv_with_a_byte_order_mark_and_crlf_reads(tmp_path):
    file = tmp_path / "excel.csv"
    file.write_bytes("x,y\r\n1.5,1.2\r\n3.5,1.2\r\n".encode("utf-8-sig"))
    assert read_robot_waypoints(file).points.tolist() == [[1.5, 1.2], [3.5, 1.2]]


def test_a_waypoint_file_without_trajectory_waypoints_says_what_is_missing(room):
    scene, folder = room
    with pytest.raises(UserError, match="takes no parameter 'file'; it takes laps, start, scale; a waypoint file "
                                        "needs --trajectory waypoints"):
        planar_trajectory(scene, None, 5, file=str(path_csv(folder)))


def test_the_ellipse_and_the_waypoints_share_one_clearance(room):
    """A path the check accepts keeps CLEARANCE everywhere between frames too (the robot is on
    the polyline); the same path moved 0.2 m towards a wall is refused naming that wall."""
    from assocbench.sim.footprint import CLEARANCE

    scene, folder = room
    poses = planar_trajectory(scene, "waypoints", 400, file=str(path_csv(folder)))
    assert scene.clearance(poses[:, :2]).min() >= CLEARANCE
    with pytest.raises(UserError, match=r"is 0\.30 m from obstacle 'wall0' .*keeps 0\.5 m"):
        planar_trajectory(scene, "waypoints", 5, file=str(path_csv(folder, [(1.5, 0.3), (7.5, 1.2)], "wall.csv")))
