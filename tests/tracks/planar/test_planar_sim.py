"""Planar track simulation: scenes, lidar, post detection, geometric mode, trajectories, sequence,
odometry and the one-line errors for bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from assocbench.errors import UserError
from assocbench.estimators.config import EstimatorConfig
from assocbench.models.range_bearing import wrap
from assocbench.models.se2 import between as true_planar_increment
from assocbench.sim.lidar import scan
from assocbench.sim.odometry import planar_odometry
from assocbench.sim.planar_scene import load_planar_scene
from assocbench.sim.planar_trajectory import CLEARANCE, planar_trajectory
from assocbench.sim.settings import LidarConfig
from assocbench.tracks.inference import track_for_scene
from assocbench.tracks.planar.geometric_sensor import geometric_detections
from assocbench.tracks.planar.post_detect import detect_posts, label_detections
from assocbench.tracks.planar.sequence import PlanarSequenceSpec, make_planar_sequence
from assocbench.tracks.planar.settings import PostDetectorConfig

SHIPPED = ("park", "post_grid", "colonnade")


def write_mjcf(tmp_path: Path, geoms: str, name: str = "user") -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(f"<mujoco><worldbody>\n{geoms}\n</worldbody></mujoco>")
    return path


def post(name: str, x: float, y: float, r: float = 0.1) -> str:
    return f'<geom name="{name}" type="cylinder" pos="{x} {y} 0.5" size="{r} 0.5"/>'


@pytest.fixture(scope="module")
def lone_post(tmp_path_factory):
    """One post 5 m from the origin, nothing else."""
    return load_planar_scene(write_mjcf(tmp_path_factory.mktemp("lone"), post("lm0", 5.0, 0.0)))


def centre_scans(scene, n: int, seed: int):
    """``n`` scans from the origin at random headings (the beams' phase against the post varies):
    (heading, detections) of those that found exactly one post."""
    cfg, out = LidarConfig(sigma_range=0.01), []
    for i in range(n):
        rng = np.random.default_rng([seed, i])
        th = rng.uniform(-np.pi, np.pi)
        det = detect_posts(scan(scene, np.array([0.0, 0.0, th]), cfg, rng), scene.post_radius, 0.01,
                           PostDetectorConfig())
        if len(det) == 1:
            out.append((th, det))
    return out


def test_shipped_planar_scenes_load_and_know_their_track():
    for name in SHIPPED:
        s = load_planar_scene(name)
        assert track_for_scene(name).name == "planar" and s.post_radius == pytest.approx(0.1)
        assert len(s.posts) >= 24 and len(s.post_geom_ids) == len(s.posts) and len(s.digest) == 16
    assert len(load_planar_scene("park").posts) >= 30
    assert {track_for_scene(n).name for n in ("room", "checkerboard", "corridor")} == {"camera"}


def test_circle_fit_centre_error_at_5m(lone_post):
    """720 beams (0.5°), σ_range = 1 cm, a post 5 m away, 1000 random beam phases: the fitted
    centre's error has RMS <= 1 cm and 95th percentile <= 2 cm; the post is found every time."""
    found = centre_scans(lone_post, 1000, seed=1)
    assert len(found) == 1000
    err = np.array([np.hypot(*(d.z[0, 0] * np.array([np.cos(d.z[0, 1] + th), np.sin(d.z[0, 1] + th)])
                               - [5.0, 0.0])) for th, d in found])
    assert np.sqrt(np.mean(err ** 2)) <= 0.01 and np.percentile(err, 95) <= 0.02


def test_first_order_covariance_matches_monte_carlo(lone_post):
    """Over 2000 scans the mean NEES of (r, φ) against R is 2 ± 10 %, and each component's
    normalised error variance is 1 ± 15 %."""
    e = []
    for th, d in centre_scans(lone_post, 2000, seed=2):
        err = d.z[0] - [5.0, -th]
        err[1] = wrap(err[1])
        L = np.linalg.cholesky(d.R[0])
        e.append((np.linalg.solve(L, err), err / np.sqrt(np.diag(d.R[0]))))
    white, scaled = (np.array(x) for x in zip(*e))
    assert 1.8 <= np.mean(np.sum(white ** 2, axis=1)) <= 2.2
    assert np.all(np.abs(np.mean(scaled ** 2, axis=0) - 1) <= 0.15)


def test_clutter_of_another_radius_and_boxes_are_rejected(tmp_path):
    """A 0.25 m drum and a box at 1.5-8 m, seen from 200 headings: never labelled as a post,
    and detected as a post at most in 2 % of the scans (3-point arcs far away)."""
    scene = load_planar_scene(write_mjcf(tmp_path, post("lm0", 0.0, -3.0) + post("drum", 4.0, 0.0, 0.25)
                                         + '<geom name="crate" type="box" pos="-3 2 0.5" size="0.3 0.2 0.5"/>'))
    false = total = 0
    for d in (1.5, 3.0, 5.0, 8.0):
        for i in range(50):
            rng = np.random.default_rng([3, i])
            pose = np.array([4.0 - d, 0.0, rng.uniform(-np.pi, np.pi)])
            s = scan(scene, pose, LidarConfig(), rng)
            det = detect_posts(s, 0.1, 0.01, PostDetectorConfig())
            labels = label_detections(det, s, scene.post_geom_ids)
            assert set(labels) <= {-1, 0}
            false += int((labels == -1).any())
            total += 1
    assert false <= 0.02 * total


@pytest.fixture(scope="module")
def park_run():
    return make_planar_sequence(PlanarSequenceSpec(scene="park", frames=500, seed=3))


def test_park_recall_precision_and_accuracy(park_run):
    """Over a 500-frame park loop: >= 95 % of the truly detectable posts are detected, >= 95 %
    of the detections are posts, and those posts' centres are within 3 cm (95th percentile)."""
    seq = park_run
    visible = sum(int(v.sum()) for v in seq.visible)
    hit = sum(int(np.isin(np.flatnonzero(v), lab).sum()) for v, lab in zip(seq.visible, seq.labels))
    labels = np.concatenate(seq.labels)
    assert hit / visible >= 0.95 and np.mean(labels >= 0) >= 0.95
    err = []
    for pose, z, lab in zip(seq.poses, seq.z, seq.labels):
        ang = z[:, 1] + pose[2]
        c = pose[:2] + z[:, :1] * np.column_stack([np.cos(ang), np.sin(ang)])
        err.append(np.linalg.norm(c[lab >= 0] - seq.posts[lab[lab >= 0]], axis=1))
    assert np.percentile(np.concatenate(err), 95) <= 0.03
    assert seq.rotations.shape == (500, 3, 3) and np.allclose(seq.positions[:, :2], seq.poses[:, :2])


def test_sequence_is_reproducible_bit_for_bit(park_run):
    again = make_planar_sequence(PlanarSequenceSpec(scene="park", frames=500, seed=3))
    assert np.array_equal(park_run.poses, again.poses) and np.array_equal(park_run.visible, again.visible)
    for a, b in ((park_run.z, again.z), (park_run.R, again.R), (park_run.labels, again.labels)):
        assert all(np.array_equal(x, y) for x, y in zip(a, b))
    other = make_planar_sequence(PlanarSequenceSpec(scene="park", frames=20, seed=4))
    assert not np.array_equal(other.z[0], park_run.z[0])


def test_geometric_mode_occlusion(tmp_path):
    """lm1 hides behind lm0, lm3 behind a box, lm4 is out of range; lm0 and lm2 are seen with
    the true range and bearing plus noise of the configured σ."""
    scene = load_planar_scene(write_mjcf(tmp_path, post("lm0", 3, 0) + post("lm1", 6, 0) + post("lm2", 0, 4)
                                         + post("lm3", -5, 0) + post("lm4", 0, -12)
                                         + '<geom name="box" type="box" pos="-2 0 0.5" size="0.2 0.5 0.5"/>'))
    cfg = LidarConfig(mode="geometric", sigma_range=0.02, sigma_bearing_deg=1.0)
    zs = []
    for i in range(300):
        det, labels, visible = geometric_detections(scene, np.array([0.0, 0.0, 0.3]), cfg, np.random.default_rng(i))
        assert visible.tolist() == [True, False, True, False, False] and sorted(labels) == [0, 2]
        zs.append(det.z[np.argsort(labels)])
    zs = np.array(zs)
    assert np.allclose(zs.mean(axis=0), [[3, -0.3], [4, np.pi / 2 - 0.3]], atol=0.01)
    assert np.allclose(zs.std(axis=0), [[0.02, np.deg2rad(1.0)]] * 2, rtol=0.15)


def test_geometric_sequence_sees_more_than_lidar_and_is_labelled():
    seq = make_planar_sequence(PlanarSequenceSpec(scene="post_grid", frames=50, lidar=LidarConfig(mode="geometric")))
    assert all(np.array_equal(np.sort(lab), np.flatnonzero(v)) for lab, v in zip(seq.labels, seq.visible))


@pytest.mark.parametrize("name", SHIPPED)
def test_default_loops_are_collision_free_closed_and_drive_forwards(name):
    scene = load_planar_scene(name)
    poses = planar_trajectory(scene, None, 500, 0)
    assert scene.clearance(poses[:, :2]).min() >= CLEARANCE
    step = np.diff(poses[:, :2], axis=0)
    assert 0.08 <= np.linalg.norm(step, axis=1).min() and np.linalg.norm(step, axis=1).max() <= 0.2
    heading_error = wrap(np.arctan2(step[:, 1], step[:, 0]) - poses[:-1, 2])
    assert np.abs(heading_error).max() < 0.1
    assert np.linalg.norm(poses[-1, :2] - poses[0, :2]) <= 0.2   # back where it started: a loop closure


def test_user_mjcf_gets_a_collision_free_ellipse(tmp_path):
    ring = "".join(post(f"lm{i}", 6 * np.cos(a), 4 * np.sin(a)) for i, a in enumerate(np.linspace(0, 6, 12)))
    scene = load_planar_scene(write_mjcf(tmp_path, ring + post("clutter", 0, 0, 0.5)))
    poses = planar_trajectory(scene, None, 300, 0)
    assert scene.clearance(poses[:, :2]).min() >= CLEARANCE
    with pytest.raises(UserError, match="no scripted loop"):
        planar_trajectory(scene, "loop", 300, 0)


@pytest.mark.parametrize("geoms,message", [
    ('<geom name="box" type="box" size="1 1 1"/>', "has no posts: add cylinder geoms named lm0"),
    (post("lm0", 1, 1) + post("lm1", 3, 1, 0.2), "posts must share one radius, found radii 0.1, 0.2"),
    (post("lm0", 1, 1) + '<geom name="lm1" type="box" size="1 1 1"/>', "posts must be cylinders, but lm1 is not"),
])
def test_bad_scenes_are_one_line_errors(tmp_path, geoms, message):
    with pytest.raises(UserError, match=message) as err:
        load_planar_scene(write_mjcf(tmp_path, geoms))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kwargs,message", [
    ({"beams": 0}, "lidar.beams must be an integer in"), ({"sigma_range": -0.1}, "lidar.sigma_range must be"),
    ({"dropout": 1.0}, "lidar.dropout must be"), ({"fov_deg": 0}, "lidar.fov_deg must be"),
    ({"mode": "sonar"}, "lidar.mode must be one of lidar, geometric"),
])
def test_bad_lidar_settings_are_one_line_errors(kwargs, message):
    with pytest.raises(UserError, match=message):
        LidarConfig(**kwargs)


def test_bad_detector_settings_and_trajectories_are_one_line_errors():
    with pytest.raises(UserError, match="posts.min_points must be an integer in"):
        PostDetectorConfig(min_points=1)
    scene = load_planar_scene("park")
    with pytest.raises(UserError, match="unknown planar trajectory 'spiral': choose one of loop, ellipse"):
        planar_trajectory(scene, "spiral", 10, 0)
    with pytest.raises(UserError, match="takes no parameter 'speed'"):
        planar_trajectory(scene, None, 10, 0, speed=2)


def test_dropout_and_partial_field_of_view():
    scene = load_planar_scene("park")
    pose = planar_trajectory(scene, None, 500, 0)[0]
    full = scan(scene, pose, LidarConfig(dropout=0.5), np.random.default_rng(0))
    assert 0.4 <= np.mean(np.isnan(full.ranges[full.geom >= 0])) <= 0.6
    front = scan(scene, pose, LidarConfig(fov_deg=90, beams=91), np.random.default_rng(0))
    assert np.allclose(front.angles[[0, 45, 90]], np.deg2rad([-45, 0, 45])) and not front.full_circle


def test_planar_odometry():
    poses = np.array([[1.0, 2.0, 3.0], [1.5, 2.2, -3.1]])
    inc = true_planar_increment(poses[0], poses[1])
    c, s = np.cos(poses[0, 2]), np.sin(poses[0, 2])
    assert np.allclose(poses[0, :2] + [c * inc[0] - s * inc[1], s * inc[0] + c * inc[1]], poses[1, :2])
    assert np.isclose(wrap(poses[0, 2] + inc[2]), poses[1, 2]) and abs(inc[2]) < 0.2
    cfg = EstimatorConfig(odometry_sigma_translation=0.02, odometry_sigma_rotation=1.0, odometry_miscalibration=2.0)
    draws = np.array([planar_odometry(poses, 1, cfg, seed).increment - inc for seed in range(4000)])
    assert np.allclose(draws.std(axis=0), 2 * np.array([0.02, 0.02, np.deg2rad(1.0)]), rtol=0.05)
    m = planar_odometry(poses, 1, cfg, 7)
    assert np.allclose(m.covariance, np.diag([0.02 ** 2, 0.02 ** 2, np.deg2rad(1.0) ** 2]))
    assert np.array_equal(m.increment, planar_odometry(poses, 1, cfg, 7).increment)
