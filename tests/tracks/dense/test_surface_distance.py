"""Distance to the true surfaces of a MuJoCo scene (the dense map's error): every analytic geom type
against points at known offsets in its own (rotated) frame, the scene minimum, and refusals."""

from types import SimpleNamespace

import numpy as np
import pytest

from assocbench import _runtime  # noqa: F401

# isort: split
import mujoco  # after assocbench: MUJOCO_GL is set before mujoco loads

# isort: split
from assocbench.errors import UserError
from assocbench.tracks.dense.surface import surface_distance

SCENE = """
<mujoco>
  <asset><mesh name="tet" vertex="0 0 0  1 0 0  0 1 0  0 0 1"/></asset>
  <worldbody>
    <geom name="box" type="box" pos="0 0 1" euler="30 20 10" size="0.3 0.2 0.1"/>
    <geom name="cyl" type="cylinder" pos="3 0 1" euler="0 40 0" size="0.25 0.5"/>
    <geom name="ball" type="sphere" pos="0 3 1" size="0.4"/>
    <geom name="pill" type="capsule" pos="3 3 1" euler="20 0 0" size="0.2 0.3"/>
    <geom name="panel" type="plane" pos="-3 0 1" xyaxes="0 1 0 0 0 1" size="0.5 0.4 0.1"/>
    <geom name="ground" type="plane" pos="0 0 -5" size="0 0 1"/>
    <geom name="hidden_egg" type="ellipsoid" pos="10 10 10" size="0.1 0.2 0.3" group="3"/>
    <geom name="hidden_tet" type="mesh" mesh="tet" pos="-10 10 10" group="4"/>
  </worldbody>
</mujoco>
"""

# (geom, local offset q in the geom's frame, distance to its surface)
CASES = [
    ("box", (0.37, 0.05, -0.02), 0.07),            # off a face
    ("box", (0.27, 0.0, 0.0), 0.03),               # inside, nearest the x face
    ("box", (0.0, 0.0, 0.06), 0.04),               # inside, nearest the z face
    ("box", (0.36, 0.28, 0.0), 0.1),               # off an edge (0.06, 0.08)
    ("box", (0.33, 0.24, 0.22), 0.13),             # off a corner (0.03, 0.04, 0.12)
    ("cyl", (0.35 * 0.6, 0.35 * 0.8, 0.2), 0.1),   # off the side
    ("cyl", (0.2, 0.0, 0.1), 0.05),                # inside, nearest the side
    ("cyl", (0.1, 0.0, 0.57), 0.07),               # off a cap
    ("cyl", (0.0, 0.28, -0.54), 0.05),             # off the rim (0.03, 0.04)
    ("ball", (0.55 * 0.6, 0.0, 0.55 * 0.8), 0.15),
    ("ball", (0.0, 0.1, 0.0), 0.3),                # inside
    ("pill", (0.25, 0.0, 0.1), 0.05),              # off the cylinder part
    ("pill", (0.0, 0.0, 0.58), 0.08),              # off the tip
    ("pill", (0.0, 0.18, 0.54), 0.1),              # off the hemisphere, diagonally (0.18, 0.24) from its centre
    ("pill", (0.05, 0.0, 0.0), 0.15),              # inside
    ("panel", (0.1, 0.2, 0.3), 0.3),               # in front of the rectangle
    ("panel", (0.1, 0.2, -0.3), 0.3),              # behind it: unsigned
    ("panel", (0.8, 0.0, 0.4), 0.5),               # beyond an edge (0.3, 0, 0.4)
    ("panel", (0.56, -0.48, 0.0), 0.1),            # beyond a corner, in its plane (0.06, 0.08)
    ("ground", (100.0, -50.0, 2.0), 2.0),          # size 0 0: infinite
]


@pytest.fixture(scope="module")
def scene():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return SimpleNamespace(model=model, data=data)


def gid(scene, name: str) -> int:
    return mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, name)


def world_point(scene, name: str, q) -> np.ndarray:
    g = gid(scene, name)
    return scene.data.geom_xpos[g] + scene.data.geom_xmat[g].reshape(3, 3) @ np.asarray(q)


def test_distance_to_each_geom_type_is_analytic(scene):
    for name, q, want in CASES:
        p = world_point(scene, name, q)[None]
        assert surface_distance(p, scene, [gid(scene, name)])[0] == pytest.approx(want, abs=1e-9), (name, q)
        if name != "ground":   # near its own geom, the scene's nearest surface is that geom's
            assert surface_distance(p, scene)[0] == pytest.approx(want, abs=1e-9), (name, q)


def test_points_on_the_surface_are_at_zero(scene):
    on = [("box", (0.3, 0.1, -0.05)), ("cyl", (0.0, 0.25, 0.3)), ("ball", (0.0, 0.0, -0.4)),
          ("pill", (0.0, 0.2, -0.3)), ("panel", (0.5, -0.4, 0.0)), ("ground", (7.0, 3.0, 0.0))]
    pts = np.array([world_point(scene, n, q) for n, q in on])
    np.testing.assert_allclose(surface_distance(pts, scene), 0.0, atol=1e-12)


def test_scene_distance_is_the_least_over_geoms_and_a_million_points_run(scene):
    rng = np.random.default_rng([5, 1])
    pts = rng.uniform([-4, -1, -1], [4, 4, 3], size=(1_000_000, 3))
    d = surface_distance(pts, scene)
    assert d.shape == (1_000_000,) and np.all(np.isfinite(d)) and np.all(d >= 0)
    rendered = [gid(scene, n) for n in ("box", "cyl", "ball", "pill", "panel", "ground")]
    each = np.column_stack([surface_distance(pts[:20000], scene, [g]) for g in rendered])
    np.testing.assert_array_equal(d[:20000], each.min(axis=1))   # the bounding-sphere skip loses nothing


def test_a_bare_model_and_nan_points(scene):
    p = np.array([world_point(scene, "ball", (0.0, 0.0, 0.5)), [np.nan, 0.0, 0.0]])
    d = surface_distance(p, scene.model)
    assert d[0] == pytest.approx(0.1, abs=1e-9) and np.isnan(d[1])


@pytest.mark.parametrize("geom, kind", [("ellipsoid", "ellipsoid"), ("mesh", "mesh")])
def test_a_rendered_geom_without_a_closed_form_is_a_one_line_error(geom, kind):
    asset = '<asset><mesh name="tet" vertex="0 0 0  1 0 0  0 1 0  0 0 1"/></asset>'
    body = {"ellipsoid": '<geom name="egg" type="ellipsoid" size="0.1 0.2 0.3"/>',
            "mesh": '<geom name="rock" type="mesh" mesh="tet"/>'}[geom]
    model = mujoco.MjModel.from_xml_string(f"<mujoco>{asset}<worldbody><geom type='box' size='1 1 1'/>{body}"
                                           f"</worldbody></mujoco>")
    with pytest.raises(UserError, match=f"has type {kind}; the surface error knows only box, plane") as err:
        surface_distance(np.zeros((3, 3)), model)
    assert "\n" not in str(err.value)


def test_unrendered_geoms_are_skipped_unless_asked_for(scene):
    surface_distance(np.zeros((1, 3)), scene)      # the hidden ellipsoid and mesh (groups 3, 4) are not surfaces
    with pytest.raises(UserError, match="hidden_egg has type ellipsoid"):
        surface_distance(np.zeros((1, 3)), scene, [gid(scene, "hidden_egg")])
    with pytest.raises(UserError, match="geom id 99 is not in the scene"):
        surface_distance(np.zeros((1, 3)), scene, [99])


def test_bad_points_and_scene_are_one_line_errors(scene):
    with pytest.raises(UserError, match=r"\(n, 3\) array, got shape \(4,\)"):
        surface_distance(np.zeros(4), scene)
    with pytest.raises(UserError, match="a scene .* or a mujoco.MjModel, got str"):
        surface_distance(np.zeros((1, 3)), "room")
