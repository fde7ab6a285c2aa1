"""The depth sensor on real MuJoCo renders: exact downsampling, the noise model, grazing dropouts,
per-pixel truth, frames that see nothing, and refused settings."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from assocbench.errors import UserError
from assocbench.models.camera import look_at
from assocbench.models.depth_frame import NO_GEOM
from assocbench.sim.render import FrameRenderer
from assocbench.sim.scene import load_scene
from assocbench.tracks.dense.depth_sensor import depth_frame, downsample_intrinsics
from assocbench.tracks.dense.settings import DepthConfig

W, H = 640, 480
EXACT = DepthConfig(downsample=1, sigma_base=0.0, sigma_quad=0.0)   # full resolution, noise-free


def write_scene(tmp_path, name: str, body: str) -> str:
    """A test MJCF: clip planes 5 cm .. 40 m (extent pinned at 10), 4x multisampling, one site."""
    path = tmp_path / f"{name}.xml"
    path.write_text(f"""<mujoco model="{name}">
  <statistic extent="10"/>
  <visual><global offwidth="{W}" offheight="{H}" fovy="60"/><quality offsamples="4"/>
    <map znear="0.005" zfar="4"/></visual>
  <worldbody>
{body}
  </worldbody>
</mujoco>""")
    return str(path)


@pytest.fixture(scope="module")
def walls(tmp_path_factory):
    """A wall whose face is the plane x = 10, and a wall turned 30° about z around (10, 100, 0)."""
    path = write_scene(tmp_path_factory.mktemp("walls"), "walls", """
    <geom name="front" type="box" pos="10.1 0 0" size="0.1 20 20"/>
    <geom name="tilted" type="box" pos="10 100 0" euler="0 0 30" size="0.1 20 20"/>
    <site name="lm0" pos="10 0 0" zaxis="-1 0 0"/>""")
    scene = load_scene(path)
    with FrameRenderer(scene, W, H) as renderer:
        yield scene, renderer


@pytest.fixture(scope="module")
def floor(tmp_path_factory):
    """An open floor (z = 0, 200 m across) under an empty sky."""
    path = write_scene(tmp_path_factory.mktemp("floor"), "floor", """
    <geom name="floor" type="box" pos="0 0 -0.1" size="100 100 0.1"/>
    <site name="lm0" pos="0 0 0"/>""")
    scene = load_scene(path)
    with FrameRenderer(scene, W, H) as renderer:
        yield scene, renderer


def forward(p) -> tuple[np.ndarray, np.ndarray]:
    """Pose at ``p`` looking along +x."""
    p = np.asarray(p, float)
    return look_at(p, p + [1.0, 0.0, 0.0]), p


def sense(renderer: FrameRenderer, R, p, cfg: DepthConfig = DepthConfig(), k: int = 0):  # noqa: B008 - frozen
    depth, geom = renderer.render_depth(R, p)
    return depth_frame(depth, geom, R, p, renderer.K, cfg, np.random.default_rng([0, k, 17]))


def world(frame) -> np.ndarray:
    """Measured points in world coordinates (H, W, 3)."""
    return frame.vertices @ frame.R.T + frame.t


def tilted_plane(scene) -> tuple[np.ndarray, np.ndarray]:
    """Unit normal and a point of the tilted wall's -x face (the one the camera sees)."""
    gid = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "tilted")
    x_axis = scene.data.geom_xmat[gid].reshape(3, 3)[:, 0]
    return -x_axis, scene.data.geom_xpos[gid] - 0.1 * x_axis


@pytest.mark.parametrize("s", [1, 2, 3, 4])
def test_downsampling_keeps_each_kept_pixel_ray(walls, s):
    """K' = (W//s, H//s, f/s, cx/s, cy/s) exactly; noise-free vertices of a fronto-parallel wall at
    2.5 m and of a wall turned 30° land on the true planes within 1 mm, and each kept pixel's vertex
    is the full-resolution vertex of pixel (s·i, s·j)."""
    scene, renderer = walls
    K = renderer.K
    cfg = DepthConfig(downsample=s, sigma_base=0.0, sigma_quad=0.0)
    assert downsample_intrinsics(K, s) == type(K)(W // s, H // s, K.f / s, K.cx / s, K.cy / s)
    R, p = forward([7.5, 0.0, 0.0])
    frame, full = sense(renderer, R, p, cfg), sense(renderer, R, p, EXACT)
    assert frame.K == downsample_intrinsics(K, s) and frame.depth.shape == (H // s, W // s)
    assert frame.valid[1:-1, 1:-1].all()   # the border rows and columns lack a neighbour for a normal
    assert np.nanmax(np.abs(world(frame)[..., 0] - 10.0)) < 1e-3
    np.testing.assert_allclose(frame.vertices, full.vertices[::s, ::s][:H // s, :W // s], rtol=0, atol=1e-12)
    R, p = forward([7.0, 100.0, 0.0])
    tilted = sense(renderer, R, p, cfg)
    n, q = tilted_plane(scene)
    off_plane = (world(tilted) - q) @ n
    assert tilted.valid[1:-1, 1:-1].all() and np.nanmax(np.abs(off_plane)) < 1e-3


@pytest.mark.parametrize("distance", [1.0, 3.0, 6.0])
def test_axial_noise_grows_with_depth_squared(walls, distance):
    """Over the 76 800 pixels of a wall at ``distance``, the depth error has mean ~0 and standard
    deviation sigma(z) = 1.2 mm + 1.9 mm/m² · z² within 10 %; the same rng gives the same frame."""
    _, renderer = walls
    cfg = DepthConfig(max_depth=20.0)
    R, p = forward([10.0 - distance, 0.0, 0.0])
    frame = sense(renderer, R, p, cfg)
    z_true = frame.true_points[..., 0] - p[0]
    err = (frame.depth - z_true)[np.isfinite(frame.depth)]
    sigma = 0.0012 + 0.0019 * distance**2
    assert err.size > 0.99 * frame.depth.size
    assert abs(np.std(err) / sigma - 1) < 0.10
    assert abs(np.mean(err)) < 0.05 * sigma
    np.testing.assert_array_equal(frame.depth, sense(renderer, R, p, cfg).depth)
    assert not np.array_equal(frame.depth, sense(renderer, R, p, cfg, k=1).depth, equal_nan=True)


@pytest.mark.parametrize("grazing_deg", [60.0, 75.0])
def test_floor_drops_out_beyond_the_grazing_angle_only(floor, grazing_deg):
    """A floor seen from 1 m up, pitched 30° down, spans incidence angles 30°..90°: every pixel
    whose ray meets it more than ``grazing_deg`` (+0.5°) from the normal is missing, every pixel
    below ``grazing_deg`` (−0.5°) is there."""
    _, renderer = floor
    p = np.array([0.0, 0.0, 1.0])
    R = look_at(p, p + [np.cos(np.radians(30)), 0.0, -np.sin(np.radians(30))])
    cfg = DepthConfig(sigma_base=0.0, sigma_quad=0.0, grazing_deg=grazing_deg, max_depth=50.0)
    frame = sense(renderer, R, p, cfg)
    K = frame.K
    u, v = np.meshgrid((np.arange(K.width) - K.cx) / K.f, (np.arange(K.height) - K.cy) / K.f)
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ R.T
    incidence = np.degrees(np.arccos(np.abs(rays[..., 2]) / np.linalg.norm(rays, axis=-1)))
    hit = np.isfinite(frame.true_points[..., 0])
    beyond, within = hit & (incidence > grazing_deg + 0.5), hit & (incidence < grazing_deg - 0.5)
    assert beyond.sum() > 1000 and within.sum() > 1000
    assert np.isnan(frame.depth[beyond]).all()
    assert np.isfinite(frame.depth[within]).all()


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    """A floor, a wall (face x = 4), a crate turned 20° and a post, with a landmark site on the wall."""
    path = write_scene(tmp_path_factory.mktemp("objects"), "objects", """
    <geom name="floor" type="box" pos="0 0 -0.1" size="10 10 0.1"/>
    <geom name="wall" type="box" pos="4.1 0 1.5" size="0.1 10 1.5"/>
    <geom name="crate" type="box" pos="2.5 0.4 0.3" euler="0 0 20" size="0.3 0.3 0.3"/>
    <geom name="post" type="cylinder" pos="3 -0.8 0.5" size="0.15 0.5"/>
    <site name="lm0" pos="4 0 0.8" zaxis="-1 0 0" size="0.05"/>""")
    return load_scene(path)


def surface_distance(scene, name: str, points: np.ndarray) -> np.ndarray:
    """Unsigned distance (n,) from world points to the surface of box or cylinder geom ``name``."""
    gid = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, name)
    local = (points - scene.data.geom_xpos[gid]) @ scene.data.geom_xmat[gid].reshape(3, 3)
    size = scene.model.geom_size[gid]
    if scene.model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_CYLINDER:
        q = np.column_stack([np.hypot(local[:, 0], local[:, 1]) - size[0], np.abs(local[:, 2]) - size[1]])
    else:
        q = np.abs(local) - size
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return np.abs(outside + np.minimum(q.max(axis=1), 0.0))


@pytest.mark.parametrize("msaa", [None, 0])
def test_true_points_lie_on_the_geom_the_segmentation_names(objects, msaa):
    """Every pixel that sees something is labelled with one of the four geoms (the landmark site is
    not imaged), each geom covers many pixels, and each pixel's true point lies on the surface of
    the geom it is labelled with within 1 mm, edges included, with and without multisampling."""
    with FrameRenderer(objects, W, H, msaa=msaa) as renderer:
        p = np.array([0.0, 0.0, 0.8])
        R = look_at(p, [3.0, 0.0, 0.5])
        frame = sense(renderer, R, p)
    hit = np.isfinite(frame.true_points[..., 0])
    assert hit.all() and (frame.geom != NO_GEOM).all()
    for name in ("floor", "wall", "crate", "post"):
        gid = mujoco.mj_name2id(objects.model, mujoco.mjtObj.mjOBJ_GEOM, name)
        mine = frame.geom == gid
        assert mine.sum() > 500, name
        assert surface_distance(objects, name, frame.true_points[mine]).max() < 1e-3, name
    assert frame.valid.mean() > 0.88   # the border and the pixels beside a depth edge carry no normal


def test_a_frame_that_sees_nothing_is_all_missing(floor, walls):
    """Looking at the sky: depth, vertices, normals and true points all NaN, geom all NO_GEOM; a wall
    beyond max_depth: nothing measured, its truth kept. No warnings either way."""
    _, renderer = floor
    p = np.array([0.0, 0.0, 1.0])
    R = look_at(p, p + [0.0, 0.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        depth, geom = renderer.render_depth(R, p)
        assert np.isnan(depth).all() and (geom == NO_GEOM).all()
        sky = sense(renderer, R, p)
        R2, p2 = forward([0.0, 0.0, 0.0])
        far = sense(walls[1], R2, p2)   # the wall is 10 m away, max_depth 8 m
    for frame in (sky, far):
        assert not frame.valid.any()
        assert np.isnan(frame.depth).all() and np.isnan(frame.vertices).all() and np.isnan(frame.normals).all()
    assert np.isnan(sky.true_points).all() and (sky.geom == NO_GEOM).all()
    assert np.abs(far.true_points[..., 0] - 10.0).max() < 1e-3


@pytest.mark.parametrize("kwargs,needle", [
    ({"downsample": 0}, "depth.downsample must be an integer in [1, 16], got 0"),
    ({"downsample": -2}, "depth.downsample"),
    ({"downsample": 2.5}, "depth.downsample must be an integer"),
    ({"downsample": True}, "depth.downsample"),
    ({"sigma_base": -0.001}, "depth.sigma_base"),
    ({"sigma_quad": float("nan")}, "depth.sigma_quad"),
    ({"grazing_deg": 0.0}, "depth.grazing_deg must be a finite number in (0, 90]"),
    ({"grazing_deg": 95.0}, "depth.grazing_deg"),
    ({"dropout": 1.0}, "depth.dropout must be a finite number in [0, 1)"),
    ({"dropout": -0.1}, "depth.dropout"),
    ({"min_depth": 0.0}, "depth.min_depth"),
    ({"max_depth": float("inf")}, "depth.max_depth"),
    ({"min_depth": 3.0, "max_depth": 2.0}, "depth.min_depth (3.0) must be below depth.max_depth (2.0)"),
    ({"max_depth": "8"}, "depth.max_depth"),
])
def test_bad_depth_settings_are_one_line_errors(kwargs, needle):
    with pytest.raises(UserError) as err:
        DepthConfig(**kwargs)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_random_dropout_removes_its_share(walls):
    """dropout = 0.3 removes 30 % ± 1 % of a wall's pixels, on top of nothing else."""
    _, renderer = walls
    R, p = forward([7.0, 0.0, 0.0])
    frame = sense(renderer, R, p, DepthConfig(dropout=0.3))
    assert abs(np.isnan(frame.depth).mean() - 0.3) < 0.01


def grazing_numpy(vertices: np.ndarray) -> np.ndarray:
    """The numpy expression ``grazing_cosine`` was before it was compiled, term for term."""
    h, w = vertices.shape[:2]
    rows, cols = np.minimum(np.arange(h), h - 2), np.minimum(np.arange(w), w - 2)
    here = vertices[rows][:, cols]
    dx = vertices[rows][:, cols + 1] - here
    dy = vertices[rows + 1][:, cols] - here
    cx = dy[..., 1] * dx[..., 2] - dy[..., 2] * dx[..., 1]
    cy = dy[..., 2] * dx[..., 0] - dy[..., 0] * dx[..., 2]
    cz = dy[..., 0] * dx[..., 1] - dy[..., 1] * dx[..., 0]
    x, y, z = vertices[..., 0], vertices[..., 1], vertices[..., 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(cx * x + cy * y + cz * z) / np.sqrt((cx * cx + cy * cy + cz * cz) * (x * x + y * y + z * z))


def test_the_compiled_grazing_cosine_is_the_numpy_expression_bit_for_bit():
    from assocbench.models.camera import Intrinsics
    from assocbench.models.depth_frame import vertex_map
    from assocbench.tracks.dense.depth_sensor import grazing_cosine

    rng = np.random.default_rng(2)
    depth = 2.0 + 0.01 * rng.standard_normal((30, 40))
    depth[rng.random(depth.shape) < 0.1] = np.nan      # holes: NaN cosines around them
    depth[:3, :3] = 0.0                                 # vertices at the centre: 0/0
    V = vertex_map(depth, Intrinsics(40, 30, 35.0, 19.5, 14.5))
    np.testing.assert_array_equal(grazing_cosine(V), grazing_numpy(V))
