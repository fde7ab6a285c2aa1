"""Obstacle footprints (``sim.footprint``): a mesh obstacle is the outline of its vertices seen
from above, not the inertia-frame size MuJoCo keeps for it."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from user_room import POSTS, path_csv, walls

from assocbench.cli.main import main
from assocbench.sim import footprint

# a rock 0.8 x 0.8 m, 0.5 m tall (a square pyramid); MuJoCo turns it into its inertia frame
ROCK = '<asset><mesh name="rock" vertex="-0.4 -0.4 0  0.4 -0.4 0  0.4 0.4 0  -0.4 0.4 0  0 0 0.5"/></asset>'
AT = (3.0, 8.35)   # in the L room's wing along y, 0.6 m beyond the waypoint path's nearest point


def room_with_rock(folder) -> str:
    """The user's L room (``user_room``, planar) with the rock in its northern wing."""
    posts = [f'<geom name="lm{i}" type="cylinder" pos="{x} {y} 0.5" size="0.1 0.5"/>' for i, (x, y) in enumerate(POSTS)]
    path = folder / "rock_room.xml"
    path.write_text(f'<mujoco>{ROCK}<worldbody>\n<geom name="floor" type="plane" size="0 0 0.1"/>\n'
                    + "\n".join(walls("wall") + posts)
                    + f'\n<geom name="rock" type="mesh" mesh="rock" pos="{AT[0]} {AT[1]} 0"/>\n</worldbody></mujoco>\n')
    return str(path)


def scene_of(path: str):
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return SimpleNamespace(model=m, data=d), mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "rock")


def test_a_mesh_is_its_vertices_outline(tmp_path):
    """Reproduction: the rock's footprint was a disc of its inertia box's first half-size about
    axes turned on their side: an infinite strip along y, so a point 6.5 m from the rock read 0.00 m."""
    scene, rock = scene_of(room_with_rock(tmp_path))
    x, y = AT
    points = np.array([[x, y - 6.5], [x, y], [x + 0.4, y + 0.4]])
    dist, which = footprint.nearest_obstacle(scene, points)
    assert which[1] == which[2] == rock and dist[1] == dist[2] == 0.0   # inside, on a corner
    assert dist[0] > 1.0 and which[0] != rock                           # 6.5 m away: a post or wall is nearer
    outline = footprint.mesh_outline(scene.model, scene.data, rock)
    to_rock = footprint.polygon_distance(outline, np.array([[x + 1.4, y], [x, y - 0.9], [x + 0.7, y + 0.8], [x, y - 6.5]]))
    assert to_rock == pytest.approx([1.0, 0.5, 0.5, 6.1], abs=1e-6)
    lo, hi = footprint.extent(scene)
    assert np.allclose(outline.min(axis=0), [x - 0.4, y - 0.4]) and np.allclose(outline.max(axis=0), [x + 0.4, y + 0.4])
    assert np.all(lo <= outline.min(axis=0)) and np.all(hi >= outline.max(axis=0))


def test_a_valid_path_beside_a_mesh_rock_is_driven(tmp_path, capsys):
    """Reproduction: the L room's waypoint path, 0.6 m or more from a mesh rock, was refused as
    0.00 m from it (a leg 5-6.5 m away ran down the false strip)."""
    scene = room_with_rock(tmp_path)
    path_csv(tmp_path)
    code = main(["run", "--scene", scene, "--method", "mnn", "--frames", "10", "--set", "trajectory=waypoints",
                 "--set", "trajectory_params.file=path.csv", "--out", str(tmp_path / "out"), "--format", "csv"])
    assert code == 0, capsys.readouterr().err


def test_the_convex_hull_and_distance_of_degenerate_outlines():
    """A mesh seen edge-on is a segment; one point is a point."""
    segment = footprint.convex_hull(np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]]))
    assert segment.tolist() == [[0.0, 0.0], [2.0, 0.0]]
    assert footprint.polygon_distance(segment, np.array([[1.0, 1.0], [3.0, 0.0]])).tolist() == [1.0, 1.0]
    square = footprint.convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float))
    assert len(square) == 4 and footprint.polygon_distance(square, np.array([[0.5, 0.5], [2, 0.5]])).tolist() == [0.0, 1.0]
