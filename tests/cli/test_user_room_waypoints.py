"""A user's own room on the lidar tracks (issue 26 item 2): an L-shaped room the test writes, with
posts placed here and walls at non-right angles, where no default ellipse fits, driven along a
waypoint file through the real command line, open and closed loop; a bad waypoint file is one
line, exit 2, and no output folder."""

from __future__ import annotations

import pandas as pd
import pytest
from user_room import PATH, path_csv, room_mjcf

from assocbench.cli.main import main
from tests.cli.test_cli import ROOT, assert_one_line_error


def run_args(scene, out, file="path.csv", frames=30) -> list[str]:
    return ["run", "--method", "jcbb", "--scene", str(scene), "--frames", str(frames), "--trajectory", "waypoints",
            "--set", f"trajectory_params.file={file}", "--out", str(out)]


@pytest.mark.parametrize("loop", [False, True], ids=["open", "closed"])
@pytest.mark.parametrize("track", ["planar", "lines"])
def test_an_l_shaped_user_room_drives_its_waypoint_path(tmp_path, capsys, track, loop):
    scene = room_mjcf(tmp_path, track)
    path_csv(tmp_path)                                   # found next to the scene: the name is relative
    out = tmp_path / "out"
    assert main(run_args(scene, out) + (["--loop"] if loop else [])) == 0
    header = capsys.readouterr().out.splitlines()[0]
    assert "trajectory waypoints, 30 frames" in header, header
    row = pd.read_csv(out / "summary.csv").iloc[0]
    assert row.status == "ok" and row.trajectory == "waypoints"
    assert row.recall >= 0.9 and row.precision >= 0.95, row
    if loop:
        assert row.diverged_at == -1 and row.ate_rmse < 0.05, row   # m
        truth = pd.read_csv(out / "truth.txt", sep=" ", header=None, comment="#")
        assert truth.iloc[0, 1:3].tolist() == pytest.approx(PATH[0]) and truth.iloc[-1, 1:3].tolist() == pytest.approx(PATH[-1])


def test_the_refused_default_loop_says_how_to_give_a_path(tmp_path, capsys):
    """The L room has no collision-free ellipse; the refusal names the setting and a file's form."""
    scene = room_mjcf(tmp_path, "planar")
    code = main(["run", "--method", "jcbb", "--scene", str(scene), "--frames", "5", "--out", str(tmp_path / "o")])
    assert_one_line_error(capsys, code, "no collision-free default loop", "--trajectory waypoints",
                          "trajectory_params.file=path.csv", "header 'x,y'")
    assert not (tmp_path / "o").exists()


BAD = {
    "missing.csv": (None, ["'missing.csv' not found", "x, y (m)"]),
    "ragged.csv": ("x,y\n1.3,1.2\n1.2\n", ["line 3: 1 values for 2 columns"]),
    "word.csv": ("x,y\n1.3,1.2\n1.2,north\n", ["line 3: y = 'north' is not a number"]),
    "nan.csv": ("x,y\n1.3,1.2\nnan,7.3\n", ["line 3: x is nan; every value must be finite"]),
    "header.csv": ("x,z\n1.3,1.2\n1.2,7.3\n", ["the header must name x and y"]),
    "one.csv": ("x,y\n1.3,1.2\n", ["has 1 waypoint(s); give at least 2"]),
    "broken.yaml": ("- {position: [1.3, 1.2]\n- {position: [1.2, 7.3]}\n", ["malformed YAML"]),
    "flat.yaml": ("- {position: [1.3, 1.2, 0]}\n- {position: [1.2, 7.3]}\n", ["position must be [x, y]"]),
    "outside.csv": ("x,y\n1.3,1.2\n30,1.2\n", ["waypoint 2 (line 3 of outside.csv, at x 30.00 m, y 1.20 m) is "
                                               "outside the scene", "move it inside"]),
    "post.csv": ("x,y\n1.3,1.2\n2.1,3.7\n", ["waypoint 2 (line 3 of post.csv, at x 2.10 m, y 3.70 m) is 0.10 m from "
                                             "obstacle 'lm0'", "move the waypoint"]),
    "leg.csv": ("x,y\n1.3,1.2\n2.1,2.6\n2.1,7.3\n", ["the leg from waypoint 2 (line 3 of leg.csv, at x 2.10 m, "
                                                     "y 2.60 m) to waypoint 3 passes 0.00 m from obstacle 'lm0'",
                                                     "add a waypoint to steer around it"]),
    "repeat.csv": ("x,y\n1.3,1.2\n1.3,1.2\n", ["line 3: the waypoint repeats the one before it"]),
    "binary.csv": (b"x,y\n\xff\xfe\x00\n", ["cannot read waypoint file", "codec can't decode"]),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_a_bad_waypoint_file_is_one_line_exit_2_and_no_output(tmp_path, capsys, name):
    scene = room_mjcf(tmp_path, "planar")
    text, needles = BAD[name]
    if isinstance(text, bytes):
        (tmp_path / name).write_bytes(text)
    elif text is not None:
        (tmp_path / name).write_text(text)
    out = tmp_path / "out"
    assert_one_line_error(capsys, main(run_args(scene, out, file=name, frames=2)), *needles)
    assert not out.exists()


def test_the_documented_example_room_is_the_tested_one(tmp_path):
    """``examples/l_room/`` (the planar and lines pages' example) is what ``tests/user_room.py`` writes."""
    from pathlib import Path

    example = Path(ROOT) / "examples" / "l_room"
    written = [room_mjcf(tmp_path, "planar"), room_mjcf(tmp_path, "lines"), path_csv(tmp_path)]
    for path in written:
        assert (example / path.name).read_text() == path.read_text(), path.name
