"""Lines track scenes: the map from lw* box walls, which line each beam hits, the shipped scenes and
their loops, and one-line errors for bad MJCF."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from assocbench.errors import UserError
from assocbench.models.range_bearing import wrap
from assocbench.sim.lidar import cast, scan
from assocbench.sim.line_scene import beam_lines, load_line_scene, visible_lines
from assocbench.sim.planar_trajectory import CLEARANCE, planar_trajectory
from assocbench.sim.scene import shipped_scenes
from assocbench.sim.settings import LidarConfig
from assocbench.tracks.inference import track_for_scene

LINES = ("office", "hallway", "furnished")


def write_mjcf(tmp_path: Path, geoms: str, name: str = "walls") -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(f'<mujoco><worldbody>\n<geom name="floor" type="plane" size="20 20 0.1"/>\n{geoms}\n'
                    f'</worldbody></mujoco>')
    return path


def box(name: str, x: float, y: float, hx: float, hy: float, yaw_deg: float = 0.0, extra: str = "") -> str:
    return (f'<geom name="{name}" type="box" pos="{x} {y} 0.6" euler="0 0 {yaw_deg}" '
            f'size="{hx} {hy} 0.6"{extra}/>')


def test_rotated_box_faces_are_hand_computed_lines(tmp_path):
    """A 2 m x 0.3 m wall at (3, 1) turned 30°: u = (cos 30°, sin 30°), v = (−sin 30°, cos 30°);
    the ±u faces lie on (30°, u·c ± 1) (the −u face flipped from (210°, 1 − u·c)), the ±v faces on
    (−60°, −(v·c + 0.15)) (flipped from (120°, v·c + 0.15) < 0) and (−60°, 0.15 − v·c)."""
    scene = load_line_scene(write_mjcf(tmp_path, box("lw0", 3, 1, 1.0, 0.15, 30)))
    a = np.pi / 6
    u, v, c = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)]), np.array([3.0, 1.0])
    expected = [(a, u @ c + 1.0), (a, u @ c - 1.0), (-np.pi / 3, -(v @ c + 0.15)), (-np.pi / 3, -(v @ c) + 0.15)]
    assert scene.lines.shape == (4, 2)
    np.testing.assert_allclose(scene.lines, expected, atol=1e-9)
    assert np.all(scene.lines[:, 1] >= 0)
    ends = scene.segments[0]                 # the +u face: c + u ± 0.15 v
    np.testing.assert_allclose(sorted(map(tuple, ends)), sorted([tuple(c + u + 0.15 * v), tuple(c + u - 0.15 * v)]),
                               atol=1e-9)
    np.testing.assert_array_equal(scene.segment_line, [0, 1, 2, 3])
    # outward normals: +u, −u, +v, −v, each pointing from the box's centre through its face
    np.testing.assert_allclose(scene.segment_normal, [u, -u, v, -v], atol=1e-12)
    mid = scene.segments.mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", mid - c, scene.segment_normal) > 0)


def test_collinear_faces_are_one_line_with_several_segments(tmp_path):
    """Two walls on y = 2 with a door between them, a perpendicular wall whose 10 cm end lies on
    their top face's line, and two walls whose faces meet on x = 0 (r = 0: α and α + π)."""
    geoms = (box("lw0", -2.0, 2.0, 1.5, 0.05) + box("lw1", 2.5, 2.0, 1.0, 0.05) + box("lw2", 6.0, 3.05, 0.05, 1.0)
             + box("lw3", 0.05, -5.0, 0.05, 2.0) + box("lw4", -0.05, 5.0, 0.05, 2.0))
    scene = load_line_scene(write_mjcf(tmp_path, geoms))
    top = [k for k, (al, r) in enumerate(scene.lines) if abs(al - np.pi / 2) < 1e-9 and abs(r - 2.05) < 1e-9]
    assert len(top) == 1
    assert np.sum(scene.segment_line == top[0]) == 3          # lw0's, lw1's top faces and lw2's end
    assert scene.face_line[0, 0] == -1 and scene.face_line[1, 1] == -1   # 10 cm door jambs: unmapped
    through_origin = [k for k, (_, r) in enumerate(scene.lines) if r < 1e-9]
    assert len(through_origin) == 1 and np.sum(scene.segment_line == through_origin[0]) == 2
    assert len(scene.lines) == len({(round(a, 6), round(r, 4)) for a, r in scene.lines})


@pytest.mark.parametrize("name,pose", [("office", (-3.0, -0.9, 0.3)), ("hallway", (-6.0, 0.4, 0.1)),
                                       ("furnished", (2.3, 1.0, 1.9))])
def test_beam_labels_lie_on_their_lines(name, pose):
    """Every labelled beam's true hit point (from an independent cast) lies on its map line to
    1e-6 m and within one of the line's segments; clutter beams are −1; most wall beams labelled."""
    scene, pose = load_line_scene(name), np.array(pose)
    cfg = LidarConfig(beams=720, dropout=0.2)
    s = scan(scene, pose, cfg, np.random.default_rng([3, 1]))
    labels = beam_lines(scene, s, pose)
    world = pose[2] + s.angles
    d, geom = cast(scene, np.array([pose[0], pose[1], cfg.height]), world, cfg.max_range)
    np.testing.assert_array_equal(geom, s.geom)
    p = pose[:2] + d[:, None] * np.column_stack([np.cos(world), np.sin(world)])
    hit = labels >= 0
    al, r = scene.lines[labels[hit]].T
    assert np.abs(np.einsum("ij,ij->i", p[hit], np.column_stack([np.cos(al), np.sin(al)])) - r).max() < 1e-6
    for i in np.flatnonzero(hit):
        seg = scene.segments[scene.segment_line == labels[i]]
        t = np.einsum("sj,sj->s", p[i] - seg[:, 0], seg[:, 1] - seg[:, 0]) / np.sum((seg[:, 1] - seg[:, 0]) ** 2, 1)
        assert np.any((t > -1e-6) & (t < 1 + 1e-6))
    walls = np.isin(s.geom, [w.geom for w in scene.walls])
    assert np.all(labels[~walls] == -1) and hit.sum() >= 0.9 * walls.sum() > 0
    if name == "furnished":
        assert (s.geom >= 0).sum() > walls.sum()              # the furniture is hit and is clutter
    s.distance = None                                         # one ray against the hit wall alone
    np.testing.assert_array_equal(beam_lines(scene, s, pose), labels)
    assert visible_lines(labels, len(scene.lines), 8).sum() >= 3


def test_visible_lines_counts_beams():
    assert visible_lines(np.array([0, 0, 2, -1, 2, 2]), 4, 2).tolist() == [True, False, True, False]


@pytest.mark.parametrize("name", LINES)
def test_shipped_loops_are_collision_free_closed_and_at_scene_speed(name):
    scene = load_line_scene(name)
    poses = planar_trajectory(scene, None, 500, 0)
    assert scene.clearance(poses[:, :2]).min() >= CLEARANCE
    step = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    assert 0.1 <= step.min() and step.max() <= 0.15
    heading_error = wrap(np.arctan2(*np.diff(poses[:, :2], axis=0).T[::-1]) - poses[:-1, 2])
    assert np.abs(heading_error).max() < 0.15
    assert np.linalg.norm(poses[-1, :2] - poses[0, :2]) <= 0.2


def test_shipped_scenes_know_their_track():
    tracks = {name: track_for_scene(name).name for name in shipped_scenes()}
    assert {n for n, t in tracks.items() if t == "lines"} == set(LINES)
    assert {n for n, t in tracks.items() if t == "planar"} == {"park", "post_grid", "colonnade"}
    assert {tracks[n] for n in ("room", "checkerboard", "corridor")} == {"camera"}
    sizes = {n: (len(s.walls), len(s.lines)) for n in LINES for s in [load_line_scene(n)]}
    assert all(w >= 4 and k >= 8 for w, k in sizes.values()) and sizes["hallway"][1] >= 40


def test_user_room_gets_a_collision_free_ellipse(tmp_path):
    room = (box("lw0", 0, -3.05, 4.1, 0.05) + box("lw1", 0, 3.05, 4.1, 0.05) + box("lw2", -4.05, 0, 0.05, 3)
            + box("lw3", 4.05, 0, 0.05, 3) + '<geom name="table" type="cylinder" pos="0.5 0 0.4" size="0.6 0.4"/>')
    scene = load_line_scene(write_mjcf(tmp_path, room))
    poses = planar_trajectory(scene, None, 200, 0)
    assert scene.clearance(poses[:, :2]).min() >= CLEARANCE
    with pytest.raises(UserError, match="no scripted loop"):
        planar_trajectory(scene, "loop", 200, 0)


@pytest.mark.parametrize("geoms,message", [
    (box("wall", 0, 0, 1, 1), "has no map walls: add upright box geoms named lw0"),
    ('<geom name="lw0" type="cylinder" pos="1 0 0.5" size="0.2 0.5"/>',
     "map walls must be boxes, but lw0 is a cylinder"),
    (box("lw0", 0, 0, 1, 0.0005), "map wall lw0 has a half-size of 0.0005 m, below 1 mm"),
    (box("lw0", 0, 0, 1, 0), "lw0.*a wall needs a positive half-size on every axis"),
    ('<geom name="lw0" type="box" pos="0 0 0.6" euler="20 0 0" size="1 0.1 0.6"/>', "map wall lw0 is tilted"),
    (box("lw0", 0, 0, 0.05, 0.05), "no wall face is 0.2 m long or longer"),
])
def test_bad_wall_scenes_are_one_line_errors(tmp_path, geoms, message):
    with pytest.raises(UserError, match=message) as err:
        load_line_scene(write_mjcf(tmp_path, geoms))
    assert "\n" not in str(err.value)


def test_box_turned_onto_its_side_is_still_upright(tmp_path):
    """A box rotated 90° about x has its local y axis vertical: its x and z faces are the walls."""
    scene = load_line_scene(write_mjcf(tmp_path, '<geom name="lw0" type="box" pos="2 0 0.6" euler="90 0 0" '
                                                 'size="1 0.6 0.15"/>'))
    np.testing.assert_allclose(sorted(map(tuple, np.round(scene.lines, 9))),
                               [(-np.pi / 2, 0.15), (0.0, 1.0), (0.0, 3.0), (np.pi / 2, 0.15)], atol=1e-9)


@pytest.mark.parametrize("extra", ['<site name="lm0" pos="0 0 1"/>',
                                   '<geom name="lm0" type="cylinder" size="0.1 0.5"/>'])
def test_walls_and_landmarks_in_one_scene_are_refused(tmp_path, extra):
    path = write_mjcf(tmp_path, box("lw0", 3, 0, 1, 0.1) + extra)
    with pytest.raises(UserError, match="lines tracks: name the run.s track with --track") as err:
        track_for_scene(path)
    assert "\n" not in str(err.value)
    assert track_for_scene(write_mjcf(tmp_path, box("lw0", 3, 0, 1, 0.1), "only")).name == "lines"
