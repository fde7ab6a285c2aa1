"""The dense track's scenes: what the generator writes, landmarks on real surfaces, camera paths
clear of the geometry, and depth frames that are mostly measured."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from assocbench.sim.render import FrameRenderer
from assocbench.sim.scene import load_scene, shipped_scenes
from assocbench.sim.scenegen.dense import BAY_PERIOD, DENSE_SCENES, generate
from assocbench.sim.trajectory import CLEARANCE
from assocbench.tracks.camera.sequence import SequenceSpec, trajectory_poses
from assocbench.tracks.dense.depth_sensor import depth_frame
from assocbench.tracks.dense.settings import DepthConfig

ANALYTIC = {mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_CYLINDER}


def sphere_directions(n: int = 400) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def test_shipped_dense_scenes_are_what_the_generator_writes(tmp_path):
    counts = generate(tmp_path)
    assert counts == {"bays": 114, "crates": 72}
    for name in DENSE_SCENES:
        assert (tmp_path / f"{name}.xml").read_bytes() == shipped_scenes()[name].read_bytes(), name


@pytest.mark.parametrize("name", list(DENSE_SCENES))
def test_landmarks_sit_on_surfaces_facing_out_and_geoms_are_analytic(name):
    """Only boxes, planes and cylinders (the surface error is analytic); every landmark lies
    within 1 cm of a surface behind it and has at least 0.5 m of free space along its normal."""
    scene = load_scene(name)
    assert set(scene.model.geom_type.tolist()) <= ANALYTIC
    assert len(scene.landmarks) >= 60
    for point, normal in zip(scene.landmarks, scene.normals):
        behind = scene.free_distance(point + 0.05 * normal, -normal[None])[0]
        ahead = scene.free_distance(point + 0.01 * normal, normal[None])[0]
        assert abs(behind - 0.05) < 0.01 and ahead > 0.5


@pytest.mark.parametrize("name,path", [("bays", "line"), ("crates", "circle")])
def test_default_path_stays_inside_and_clear(name, path):
    """The default trajectory (40 frames) keeps CLEARANCE from every surface in every direction,
    inside the enclosure (every ray meets a surface); the bays' line runs along the corridor
    (+x) over at least four bay periods, looking forward."""
    scene = load_scene(name)
    spec = SequenceSpec(scene=name, frames=40)
    assert spec.resolved_trajectory() == path
    rots, pos = trajectory_poses(spec, scene)
    dirs = sphere_directions()
    free = np.array([scene.free_distance(p, dirs) for p in pos])
    assert np.isfinite(free).all() and free.min() >= CLEARANCE
    if name == "bays":
        assert np.ptp(pos[:, 0]) > 4 * BAY_PERIOD and np.ptp(pos[:, 1]) < 0.1
        assert (rots[:, 0, 2] > 0.99).all()   # the optical axis (third column) along +x


@pytest.mark.parametrize("name", list(DENSE_SCENES))
def test_default_path_depth_frames_are_mostly_valid(name):
    """Over 8 frames of the default path at 640x480 (downsampled to 320x240, default noise) more
    than 70 % of the pixels have a vertex and a normal in every frame."""
    scene = load_scene(name)
    spec = SequenceSpec(scene=name, frames=8)
    rots, pos = trajectory_poses(spec, scene)
    cfg = DepthConfig()
    with FrameRenderer(scene, 640, 480) as renderer:
        shares = [depth_frame(*renderer.render_depth(R, p), R, p, renderer.K, cfg,
                              np.random.default_rng([0, k, 17])).valid.mean()
                  for k, (R, p) in enumerate(zip(rots, pos))]
    assert min(shares) > 0.7, shares
