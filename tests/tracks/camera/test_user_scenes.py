"""User scenes that just work: un-oriented landmark sites, rigs that stay inside, user paths."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.errors import UserError
from assocbench.sim.scene import load_scene, shipped_scenes
from assocbench.sim.scenegen.camera import HALL_VERTICES, SceneBuilder, polygon_hall, write_scene
from assocbench.sim.trajectory import rig_for
from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence, trajectory_poses
from assocbench.tracks.inference import track_for_scene


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def wall_distances(points: np.ndarray, vertices=HALL_VERTICES) -> np.ndarray:
    """(N, walls) signed distance of points (x, y) inside a counterclockwise convex polygon."""
    v = np.asarray(vertices, float)
    edges = np.roll(v, -1, axis=0) - v
    inward = np.column_stack([-edges[:, 1], edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
    return np.einsum("wk,nwk->nw", inward, points[:, None, :2] - v[None])


@pytest.fixture(scope="module")
def hall(tmp_path_factory):
    path, sb = write_scene(tmp_path_factory.mktemp("hall"), "hall", polygon_hall)
    return path, np.array(sb.normals)


def test_unoriented_polygon_hall_just_works(hall, capfd):
    """Six walls meeting at 105-135°, sites with no orientation: normals come from the walls,
    the camera circles inside the hall at the landmarks' height and sees and labels several
    landmarks in most frames. (Before: every normal +z, camera above the hall looking down.)"""
    path, true_normals = hall
    assert "quat=" not in "".join(line for line in path.read_text().splitlines() if "<site" in line)
    scene = load_scene(path)
    assert scene.inferred.all()
    assert angles_deg(scene.normals, true_normals).max() < 1.0
    seq = load_sequence(SequenceSpec(scene=str(path), frames=8, width=320, height=240))
    assert wall_distances(seq.positions).min() > 1.0                       # inside, clear of every wall
    heights = scene.landmarks[:, 2]
    assert np.all((seq.positions[:, 2] > heights.min()) & (seq.positions[:, 2] < heights.max()))
    labelled = np.array([np.sum(lab >= 0) for lab in seq.labels])
    assert np.sum(labelled >= 4) >= 6, labelled
    errs = np.concatenate([np.linalg.norm(f[lab >= 0] - uv[lab[lab >= 0]], axis=1)
                           for f, lab, uv in zip(seq.features, seq.labels, seq.projections)])
    assert np.median(errs) <= 0.3
    assert "warning" not in capfd.readouterr().err


SURFACES = """<mujoco><worldbody>
  <geom type="box" pos="0 2.05 1" size="3 0.05 1"/>
  <geom type="box" pos="0 -2.05 1" size="3 0.005 1"/>
  <geom type="cylinder" pos="-1.5 0 1" size="0.3 1"/>
  <geom type="plane" pos="0 0 0" size="5 5 1"/>
  <body pos="2 0 1" euler="0 0 37"><geom type="box" size="0.05 1 1"/></body>
  <site name="lm_on" pos="0 2 1"/>
  <site name="lm_embedded" pos="0.5 2.003 1.2"/>
  <site name="lm_offset" pos="-0.5 1.996 0.8"/>
  <site name="lm_board" pos="0.5 -2.045 1"/>
  <site name="lm_pillar" pos="{pillar}"/>
  <site name="lm_floor" pos="0.5 0.5 0"/>
  <site name="lm_oblique" pos="{oblique}"/>
  <site name="lm_oriented" pos="1 2 1.5" zaxis="0 -1 0"/>
</worldbody></mujoco>"""


def test_normals_inferred_on_every_kind_of_surface(tmp_path, capfd):
    """On a wall, 3 mm into it, 4 mm in front of it, on a 1 cm board, on a pillar, on the floor
    and on a wall turned 37°: the normal of the surface, towards open space, within 1°."""
    pillar_dir = np.array([np.cos(0.5), np.sin(0.5), 0.0])
    turn = np.deg2rad(37)
    oblique_n = np.array([-np.cos(turn), -np.sin(turn), 0.0])            # the -x face of the turned box
    pillar = np.array([-1.5, 0, 1.3]) + 0.3 * pillar_dir
    oblique = np.array([2, 0, 1.2]) + 0.05 * oblique_n + 0.3 * np.array([-oblique_n[1], oblique_n[0], 0])
    path = tmp_path / "surfaces.xml"
    path.write_text(SURFACES.format(pillar=" ".join(map(str, pillar)), oblique=" ".join(map(str, oblique))))
    scene = load_scene(path)
    expect = {"lm_on": [0, -1, 0], "lm_embedded": [0, -1, 0], "lm_offset": [0, -1, 0], "lm_board": [0, 1, 0],
              "lm_pillar": pillar_dir, "lm_floor": [0, 0, 1], "lm_oblique": oblique_n, "lm_oriented": [0, -1, 0]}
    want = np.array([expect[n] for n in scene.landmark_names], float)
    assert angles_deg(scene.normals, want).max() < 1.0, dict(zip(scene.landmark_names, angles_deg(scene.normals, want)))
    assert list(scene.inferred) == [n != "lm_oriented" for n in scene.landmark_names]
    assert "warning" not in capfd.readouterr().err


def tile_junctions(sb: SceneBuilder, oriented: bool = False) -> None:
    """Checker patches of four 1 cm box tiles (12 cm), the site exactly on their shared front
    corner or on the edge two of them share: on a wall facing -x, on a wall turned 37° with the
    tiles turned 25° in it, freestanding (upright and tilted), and lying on the floor turned 45°."""
    sb.box((0, 0, -0.05), (6, 6, 0.05))
    sb.box((3.05, 0, 1.5), (0.05, 3, 1.5))
    turned = np.array([-np.cos(np.deg2rad(37)), -np.sin(np.deg2rad(37)), 0.0])
    sb.wall((-2, 1, 1.5), turned, 1.0, 1.5)
    side = np.cross([0, 0, 1], turned)
    up25 = np.cos(np.deg2rad(25)) * np.array([0, 0, 1]) + np.sin(np.deg2rad(25)) * side
    tilted = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    for k, on_edge in enumerate((False, True)):
        edge = (0.06, 0.0) if on_edge else (0.0, 0.0)
        sb.tile_patch((3.0 - 0.01, -1 + 2 * k, 1.0), (-1, 0, 0), site_offset=edge, oriented=oriented)
        sb.tile_patch((-2, 1, 0.8 + k) + 0.01 * turned - 0.5 * side, turned, up25,
                      site_offset=(0.0, -0.06) if on_edge else (0.0, 0.0), oriented=oriented)
        sb.tile_patch((0.5 * k, -1, 1.2), tilted, (1, 0, 0), site_offset=edge, oriented=oriented)
        sb.tile_patch((0.5 * k, -2, 1.0), (0, -1, 0), site_offset=edge, oriented=oriented)
        sb.tile_patch((1 + k, 1, 0.01), (0, 0, 1), (1, 1, 0), site_offset=edge, oriented=oriented)


@pytest.mark.parametrize("oriented", [False, True])
def test_normals_on_the_corner_and_edge_shared_by_box_tiles(tmp_path, capfd, oriented):
    """Box tiles meet at the site: the probes end exactly on their shared corner or edge, where
    MuJoCo reports a side face as often as the front (before: 90° off, no warning). The normal
    is the tiles' front, within 1°, on walls, turned, freestanding and on the floor. A site oriented
    in the MJCF is not taken for pointing into its tiles (before: the one ray aimed at the seam
    of freestanding tiles slipped through it and said so)."""
    path, sb = write_scene(tmp_path, "junctions", tile_junctions, oriented=oriented)
    scene = load_scene(path)
    assert len(scene.normals) == 10 and scene.inferred.all() != oriented
    assert angles_deg(scene.normals, np.array(sb.normals)).max() < 1.0, angles_deg(scene.normals, np.array(sb.normals))
    assert "warning" not in capfd.readouterr().err


def test_polygon_hall_of_box_tiles(tmp_path, capfd):
    """The hexagonal hall with every patch made of four box tiles, the site on their shared
    corner: inferred normals within 1° of the walls' (before: a third of them 90° off)."""
    path, sb = write_scene(tmp_path, "tiled_hall", polygon_hall, tiles=True)
    scene = load_scene(path)
    assert scene.inferred.all()
    assert angles_deg(scene.normals, np.array(sb.normals)).max() < 1.0
    assert "warning" not in capfd.readouterr().err


FLOATING = """<mujoco><worldbody>
  <geom type="plane" pos="0 0 0" size="10 10 1"/>
  {sites}
</worldbody></mujoco>"""


@pytest.mark.parametrize("case", ["floating", "into-wall", "all-up", "on-corner"])
def test_implausible_normals_are_warned_in_one_line(tmp_path, capfd, case):
    """Sites with no orientation in mid-air, sites whose z axis points into their wall, one
    normal for landmarks spread over several walls, and sites with no orientation on a box's
    corner (top or side: a guess) each give one warning line on stderr."""
    ring = [(3 * np.cos(a), 3 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)]
    if case == "floating":
        sites = "".join(f'<site name="lm{k}" pos="{x} {y} 1.5"/>' for k, (x, y) in enumerate(ring))
    elif case == "on-corner":
        sites = "".join(f'<geom type="box" pos="{x} {y} 0.4" size="0.3 0.3 0.4"/>'
                        f'<site name="lm{k}" pos="{x + 0.3} {y - 0.3} 0.8"/>' for k, (x, y) in enumerate(ring))
    else:
        # six walls facing the centre, their inner faces 3 m out; the sites on those faces
        walls = "".join(f'<geom type="box" pos="{x * 3.05 / 3} {y * 3.05 / 3} 1.5" zaxis="{x} {y} 0" '
                        f'size="1 1.5 0.05"/>' for x, y in ring)
        axis = (lambda x, y: f"{x} {y} 0") if case == "into-wall" else (lambda x, y: "0 0 1")
        sites = walls + "".join(f'<site name="lm{k}" pos="{x} {y} {1 + k % 2}" zaxis="{axis(x, y)}"/>'
                                for k, (x, y) in enumerate(ring))
    path = tmp_path / f"{case}.xml"
    path.write_text(FLOATING.format(sites=sites))
    load_scene(path)
    load_scene(path)                                                      # said once, not at every load
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and err.startswith("assocbench: warning: scene " + case), err
    assert {"floating": "sit on no surface", "into-wall": "does not point out",
            "all-up": "does not point out", "on-corner": "sit on an edge or corner"}[case] in err


def test_shipped_scenes_load_without_warnings(capfd):
    for name in shipped_scenes():
        if track_for_scene(name).name == "camera":   # the planar scenes' posts are geoms, not sites
            assert not load_scene(name).inferred.any()
    assert capfd.readouterr().err == ""


def test_camera_is_moved_off_a_pillar_that_stands_on_the_centroid(tmp_path):
    """A 1.2 m pillar in the middle of the hall: the circle (radius 1 m about the centroid
    before) would run inside it; the rig moves to the widest free spot and shrinks the circle."""
    def hall_with_pillar(sb: SceneBuilder) -> None:
        polygon_hall(sb)
        sb.cylinder((0.0, 0.0, 1.5), 1.2, 1.5, "0.7 0.5 0.3 1")

    path, _ = write_scene(tmp_path, "pillar_hall", hall_with_pillar)
    scene = load_scene(path)
    _, pos = trajectory_poses(SequenceSpec(scene=str(path), frames=12), scene)
    assert np.linalg.norm(pos[:, :2], axis=1).min() > 1.2 + 0.25
    assert wall_distances(pos).min() > 0.25
    free = np.array([scene.free_distance(p, np.eye(3)).min() for p in pos])
    assert free.min() > 0.25                                              # never inside a solid


def fake_free(floor: float = 0.0, ceiling: float = np.inf, ahead: float = np.inf):
    """Free space of a box-shaped world: a floor, a ceiling and a far wall along -y."""
    def free(origin, dirs):
        out = np.full(len(dirs), np.inf)
        for k, d in enumerate(dirs):
            if d[2] < -0.5:
                out[k] = origin[2] - floor
            elif d[2] > 0.5:
                out[k] = ceiling - origin[2]
            elif d[1] < -0.5:
                out[k] = origin[1] - ahead
        return out
    return free


def test_rig_keeps_the_camera_between_floor_and_ceiling_and_in_front_of_the_far_wall():
    """A hall 1.5 m high whose landmarks average 1.4 m: the camera flies 0.3 m under the ceiling.
    A wall 2 m before a board the field of view would want to see from 3+ m: 0.3 m before it."""
    ring = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 2 * np.pi, 10, endpoint=False)])
    hall = 3 * ring + np.array([[0.0, 0.0, 1.3 + 0.2 * (k % 2)] for k in range(10)])
    assert rig_for(hall, -ring, 60.0, 4 / 3).center[2] == pytest.approx(1.4)  # the landmarks' mean height
    inside = rig_for(hall, -ring, 60.0, 4 / 3, fake_free(floor=0.0, ceiling=1.5))
    assert inside.view is None and inside.center[2] == pytest.approx(1.2)
    lm = np.array([[x, 0.0, z] for x in np.linspace(-4, 4, 9) for z in (1.3, 1.5)])
    wall = rig_for(lm, np.tile([0.0, -1.0, 0.0], (len(lm), 1)), 60.0, 4 / 3)
    assert wall.center[1] < -3.0                                                # the landmarks alone: 3+ m away
    walled = rig_for(lm, np.tile([0.0, -1.0, 0.0], (len(lm), 1)), 60.0, 4 / 3, fake_free(ahead=-2.0))
    assert walled.center[1] == pytest.approx(-1.7)                              # 0.3 m before the far wall


WALK_CSV = """# a walk across the hall, looking at three walls in turn
x, y, z, look_x, look_y, look_z
-1, 0, 1.4, 3, 0, 1.4
0, 0, 1.4, 0, 3, 1.4
1, 0, 1.4, -3, 0, 1.4
"""

WALK_YAML = """waypoints:
  - {position: [-1, 0, 1.4], yaw: 0, t: 0}
  - {position: [0, 0, 1.4], yaw: 90, pitch: 10, t: 3}
  - {position: [1, 0, 1.4], look_at: [-3, 0, 1.4], t: 4}
"""


def exact(**params) -> dict:
    return {"jitter_pos": 0.0, "jitter_deg": 0.0, **params}


def test_waypoint_csv_path_goes_through_every_waypoint_looking_where_told(hall):
    path, _ = hall
    (path.parent / "walk.csv").write_text(WALK_CSV)
    spec = SequenceSpec(scene=str(path), trajectory="waypoints", frames=5, trajectory_params=exact(file="walk.csv"))
    R, p = trajectory_poses(spec, load_scene(path))                       # found next to the scene
    assert np.allclose(p[[0, 2, 4]], [[-1, 0, 1.4], [0, 0, 1.4], [1, 0, 1.4]])
    assert np.allclose(R[[0, 2, 4], :, 2], [[1, 0, 0], [0, 1, 0], [-1, 0, 0]], atol=1e-9)   # optical axes
    assert np.allclose(R[1, :, 2], [np.sqrt(0.5), np.sqrt(0.5), 0])                        # turned half way
    seq = load_sequence(SequenceSpec(scene=str(path), trajectory="waypoints", frames=3, width=320, height=240,
                                     trajectory_params={"file": "walk.csv"}))
    assert all(np.sum(lab >= 0) >= 3 for lab in seq.labels)


def test_waypoint_yaml_with_headings_and_times(hall, tmp_path):
    path, _ = hall
    walk = tmp_path / "walk.yaml"
    walk.write_text(WALK_YAML)
    spec = SequenceSpec(scene=str(path), trajectory="waypoints", frames=5, trajectory_params=exact(file=str(walk)))
    R, p = trajectory_poses(spec, load_scene(path))
    assert np.allclose(p[:, 0], [-1, -2 / 3, -1 / 3, 0, 1])              # t = 0, 3, 4: slow leg, then fast
    pitch = np.deg2rad(10)
    assert np.allclose(R[3, :, 2], [0, np.cos(pitch), np.sin(pitch)])
    assert np.allclose(R[-1, :, 2], [-1, 0, 0])


def test_waypoint_file_content_enters_the_cache_key(hall, tmp_path):
    path, _ = hall
    walk = tmp_path / "walk.csv"
    walk.write_text(WALK_CSV)
    spec = SequenceSpec(scene=str(path), trajectory="waypoints", trajectory_params={"file": str(walk)})
    before = spec.key()
    assert spec.key() == before
    walk.write_text(WALK_CSV.replace("1, 0, 1.4, -3", "1.5, 0, 1.4, -3"))
    assert spec.key() != before


BAD_FILES = {
    "missing.csv": (None, "not found"),
    "walk.txt": ("x, y, z, yaw\n0, 0, 1, 0\n1, 0, 1, 0\n", "must be .csv, .yaml or .yml"),
    "header.csv": ("x, y, z\n0, 0, 1\n1, 0, 1\n", "the header must name x, y, z and either"),
    "ragged.csv": ("x, y, z, yaw\n0, 0, 1, 0\n1, 0, 1\n", "line 3: 3 values for 4 columns"),
    "word.csv": ("x, y, z, yaw\n0, 0, 1, 0\n1, north, 1, 0\n", "line 3: y = 'north' is not a number"),
    "nan.csv": ("x, y, z, yaw\n0, 0, 1, 0\n1, 0, nan, 0\n", "line 3: z is nan; every value must be finite"),
    "inf.yaml": ("- {position: [0, 0, 1], yaw: 0}\n- {position: [1, 0, .inf], yaw: 0}\n", "position[2] is inf"),
    "one.csv": ("x, y, z, yaw\n0, 0, 1, 0\n", "has 1 waypoint(s); give at least 2"),
    "empty.yaml": ("", "must hold a list of waypoints"),
    "broken.yaml": ("- {position: [0, 0, 1], yaw: 0\n- {position: [1, 0, 1]}\n", "malformed YAML"),
    "blind.yaml": ("- {position: [0, 0, 1], look_at: [0, 0, 1]}\n- {position: [1, 0, 1], yaw: 0}\n",
                   "the look-at point is the position itself"),
    "nowhere.yaml": ("- {position: [0, 0, 1]}\n- {position: [1, 0, 1], yaw: 0}\n", "give where the camera looks"),
    "time.yaml": ("- {position: [0, 0, 1], yaw: 0, t: 1}\n- {position: [1, 0, 1], yaw: 0, t: 1}\n",
                  "t must increase strictly"),
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_waypoint_files_are_refused_in_one_line_before_anything_runs(tmp_path, name):
    """Checked when the run is resolved (``run_spec``), so nothing renders and no folder appears."""
    from assocbench.harness.config import load_run_config, run_spec

    text, said = BAD_FILES[name]
    if text is not None:
        (tmp_path / name).write_text(text)
    cfg = load_run_config(sets=["trajectory=waypoints", f"trajectory_params.file={tmp_path / name}", "frames=2"])
    with pytest.raises(UserError) as err:
        run_spec(cfg)
    message = str(err.value)
    assert said in message and name in message and "\n" not in message, message


def test_waypoints_without_a_file_say_what_to_give():
    with pytest.raises(UserError, match="needs trajectory_params.file"):
        SequenceSpec(scene="room", trajectory="waypoints").resolved_trajectory()


CAMERAS = """<mujoco>
  <visual><global offwidth="320" offheight="240" fovy="60"/></visual>
  <worldbody>
    <geom type="box" pos="0 3.05 1.5" size="4 0.05 1.5"/>
    <site name="lm0" pos="0 3 1.5"/><site name="lm1" pos="1 3 1.5"/><site name="lm2" pos="0 3 2"/>
    <camera name="door" pos="-2 0 1.5" xyaxes="1 0 0 0 0 1"/>
    <camera name="corner" pos="2 0.5 1.2" xyaxes="0.8 0.6 0 0 0 1" fovy="60"/>
  </worldbody>
</mujoco>"""


def test_mjcf_cameras_path_and_named_camera(tmp_path, capfd):
    """``mjcf-cameras`` runs from the first MJCF camera to the last; naming one holds its view.
    A camera whose own fovy differs from the one frames are rendered with is named on stderr."""
    path = tmp_path / "cams.xml"
    path.write_text(CAMERAS)
    scene = load_scene(path)
    R, p = trajectory_poses(SequenceSpec(scene=str(path), trajectory="mjcf-cameras", frames=4,
                                         trajectory_params=exact()), scene)
    assert np.allclose(p[[0, -1]], [[-2, 0, 1.5], [2, 0.5, 1.2]])
    assert np.allclose(R[0, :, 2], [0, 1, 0]) and np.allclose(R[-1, :, 2], [-0.6, 0.8, 0])  # MuJoCo's -z
    assert np.allclose(R[0, :, 1], [0, 0, -1])                                               # image rows go down
    R, p = trajectory_poses(SequenceSpec(scene=str(path), trajectory="mjcf-cameras", frames=3,
                                         trajectory_params=exact(cameras="corner")), scene)
    assert np.allclose(p, [2, 0.5, 1.2]) and np.allclose(R[:, :, 2], [-0.6, 0.8, 0])
    assert "camera door has its own fovy" in capfd.readouterr().err       # MuJoCo's default is 45°
    with pytest.raises(UserError, match="has no camera 'attic': its named cameras are door, corner"):
        trajectory_poses(SequenceSpec(scene=str(path), trajectory="mjcf-cameras",
                                      trajectory_params={"cameras": ["door", "attic"]}), scene)
    with pytest.raises(UserError, match="defines no <camera>"):
        trajectory_poses(SequenceSpec(scene="room", trajectory="mjcf-cameras"), load_scene("room"))
