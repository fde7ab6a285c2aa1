"""Generator of the shipped camera scenes in ``assocbench/scenes/`` (MJCF and textures), rebuilt
with ``python -m assocbench.sim.scenegen.camera``. Every landmark is a site ``lm###`` at the
X-junction of an identical 2x2 checker patch of four thin boxes, so appearance cannot tell landmarks
apart; its z axis is the patch's outward normal. Walls carry a texture with smaller look-alike
X-junctions: distractor corners.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import SCENES_DIR

PATCH = 0.70          # side of a landmark patch (m): its outer edge corners lie PATCH/2 away
OFFSET = 0.004        # gap between wall surface and patch (m), avoids z-fighting
OFFSCREEN = (1280, 960)
# A plane's third size is the spacing of the grid it is drawn with: a fine grid multiplies the
# triangles (0.01 m made a 0.7 m patch 4900 quads and the room 30x slower to render). Planes
# here are flat-lit and textured per plane, so one coarse grid cell is enough.
PLANE_GRID = 5.0


@dataclass
class SceneBuilder:
    """Accumulates MJCF fragments for one scene."""

    name: str
    geoms: list[str] = field(default_factory=list)
    n_landmarks: int = 0
    normals: list[np.ndarray] = field(default_factory=list)   # intended normal of each landmark
    generator: str = "scenegen.camera"   # the module named in the header as the one to edit
    # MuJoCo scales the clip planes by the model's extent; a set ``extent`` pins it, so the planes
    # are ``znear * extent`` and ``zfar * extent`` metres whatever the scene's size
    znear: float = 0.005
    zfar: float = 60.0
    extent: float | None = None

    def box(self, pos, size, rgba="0.6 0.6 0.6 1", material=None) -> None:
        attrs = f'type="box" pos="{_v(pos)}" size="{_v(size)}"'
        attrs += f' material="{material}"' if material else f' rgba="{rgba}"'
        self.geoms.append(f"    <geom {attrs}/>")

    def wall(self, center, normal, half_w, half_h, material="wall") -> None:
        """A finite textured plane facing ``normal`` (planes map 2D textures; boxes do not)."""
        n = np.asarray(normal, float)
        up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
        axes = f'xyaxes="{_v(np.cross(up, n))} {_v(up)}"'
        self.geoms.append(
            f'    <geom type="plane" pos="{_v(center)}" {axes} size="{half_w:.4f} {half_h:.4f} {PLANE_GRID}" '
            f'material="{material}"/>'
        )
        # a thin box behind the plane so the wall is solid from behind as well
        self.geoms.append(
            f'    <geom type="box" pos="{_v(np.asarray(center) - 0.051 * n)}" {axes} '
            f'size="{half_w:.4f} {half_h:.4f} 0.05" rgba="0.5 0.5 0.5 1"/>'
        )

    def cylinder(self, pos, radius, half_height, rgba) -> None:
        self.geoms.append(
            f'    <geom type="cylinder" pos="{_v(pos)}" size="{radius:.4f} {half_height:.4f}" rgba="{rgba}"/>'
        )

    def landmark(self, center, normal, up=(0.0, 0.0, 1.0), size=PATCH, oriented: bool = True) -> None:
        """Add a 2x2 checker patch whose X-junction sits at ``center`` facing ``normal``; its site
        is written without orientation when ``oriented`` is False (as users often write them)."""
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        u = np.asarray(up, float) - np.dot(up, n) * n
        u /= np.linalg.norm(u)
        r = np.cross(u, n)  # right-handed (r, u, n)
        c = np.asarray(center, float)
        quat = _mat_to_quat(np.column_stack([r, u, n]))
        # a textured plane facing n: planes map a 2D texture once across their face
        self.geoms.append(
            f'    <geom type="plane" pos="{_v(c)}" quat="{_v(quat)}" size="{size / 2:.4f} {size / 2:.4f} {PLANE_GRID}" '
            f'material="landmark" group="1"/>'
        )
        self.add_site(c, n, u, oriented)

    def tile_patch(self, center, normal, up=(0.0, 0.0, 1.0), size: float = 0.24, thickness: float = 0.01,
                   oriented: bool = False, site_offset=(0.0, 0.0)) -> None:
        """A 2x2 checker patch built of four thin black/white boxes (a user's common way) whose
        shared front corner is ``center``, facing ``normal``; the site sits exactly on that corner,
        or ``site_offset`` (along right, up) from it: (size / 4, 0) puts it on the edge two tiles share."""
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        u = np.asarray(up, float) - np.dot(up, n) * n
        u /= np.linalg.norm(u)
        r = np.cross(u, n)
        c = np.asarray(center, float)
        quat = _v(_mat_to_quat(np.column_stack([r, u, n])))   # the boxes' z is their thickness
        for du, dv in ((1, 1), (-1, -1), (1, -1), (-1, 1)):
            pos = c - n * thickness / 2 + (du * r + dv * u) * size / 4
            rgba = "0.1 0.1 0.1 1" if du == dv else "0.9 0.9 0.9 1"
            self.geoms.append(f'    <geom type="box" pos="{_v(pos)}" quat="{quat}" '
                              f'size="{size / 4:.5f} {size / 4:.5f} {thickness / 2:.5f}" rgba="{rgba}"/>')
        self.add_site(c + site_offset[0] * r + site_offset[1] * u, n, u, oriented)

    def add_site(self, center, normal, up=(0.0, 0.0, 1.0), oriented: bool = True) -> None:
        """The landmark site ``lm###`` at an X-junction, its z axis along ``normal`` (no
        orientation written when ``oriented`` is False: the loader infers it from the surface)."""
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        u = np.asarray(up, float) - np.dot(up, n) * n
        u /= np.linalg.norm(u)
        quat = _mat_to_quat(np.column_stack([np.cross(u, n), u, n]))
        orientation = f' quat="{_v(quat)}"' if oriented else ""
        self.geoms.append(f'    <site name="lm{self.n_landmarks:03d}" pos="{_v(center)}"{orientation} size="0.01"/>')
        self.normals.append(n)
        self.n_landmarks += 1

    def xml(self, comment: str) -> str:
        w, h = OFFSCREEN
        body = "\n".join(self.geoms)
        statistic = "" if self.extent is None else f'\n  <statistic extent="{self.extent:g}"/>'
        return f"""<!-- {comment}
     Generated by `python -m assocbench.sim.{self.generator}`; edit the generator, not this file. -->
<mujoco model="{self.name}">{statistic}
  <visual>
    <global offwidth="{w}" offheight="{h}" fovy="60"/>
    <headlight ambient="1 1 1" diffuse="0 0 0" specular="0 0 0" active="1"/>
    <quality offsamples="4"/>
    <map znear="{self.znear:g}" zfar="{self.zfar:g}"/>
  </visual>
  <asset>
    <texture name="wall" type="2d" file="wall_tile.png"/>
    <material name="wall" texture="wall" texrepeat="0.5 0.5" texuniform="true" specular="0" shininess="0"/>
    <texture name="landmark" type="2d" file="landmark.png"/>
    <material name="landmark" texture="landmark" texrepeat="1 1" specular="0" shininess="0"/>
    <texture name="board" type="2d" file="board.png"/>
    <material name="board" texture="board" texrepeat="1 1" specular="0" shininess="0"/>
    <texture name="floor" type="2d" builtin="flat" rgb1="0.45 0.42 0.40" rgb2="0.45 0.42 0.40" width="8" height="8"/>
    <material name="floor" texture="floor" specular="0"/>
  </asset>
  <worldbody>
{body}
  </worldbody>
</mujoco>
"""


def _v(x) -> str:
    return " ".join(f"{float(a):.5f}" for a in np.ravel(x))


def _mat_to_quat(mat: np.ndarray) -> np.ndarray:
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(mat).ravel())
    return quat


WALL_GRAY = 150
BOARD_CELLS = (14, 7)
BOARD_CELL = 0.4       # m


def board_texture(px_per_cell: int = 64) -> np.ndarray:
    """Checkerboard of ``BOARD_CELLS`` cells, dark and light around the wall gray."""
    cols, rows = BOARD_CELLS
    cells = (np.add.outer(np.arange(rows), np.arange(cols)) % 2).astype(np.uint8)
    img = np.where(np.kron(cells, np.ones((px_per_cell, px_per_cell), np.uint8)) > 0, 235, 55).astype(np.uint8)
    return np.dstack([img, img, img])


def landmark_patch(size: int = 256) -> np.ndarray:
    """2x2 checker whose contrast fades to the wall gray at the border: the only corner is
    the X-junction at the centre, so the patch adds no L-corners around its landmark."""
    c = (np.arange(size) - (size - 1) / 2) / (size / 2)
    xx, yy = np.meshgrid(c, c)
    r = np.hypot(xx, yy)  # round contours: a square fade would have corners of its own
    window = np.clip((0.98 - r) / 0.4, 0.0, 1.0)
    window = 0.5 - 0.5 * np.cos(np.pi * window)
    img = WALL_GRAY + 100.0 * np.sign(xx) * np.sign(yy) * window
    img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return np.dstack([img, img, img])


def wall_tile(size: int = 256) -> np.ndarray:
    """Gray tile with small look-alike X-junctions and blobs (distractor corners)."""
    img = np.full((size, size), WALL_GRAY, np.uint8)
    rng = np.random.default_rng(7)
    for cx, cy, s in ((64, 64, 7), (190, 150, 5)):
        img[cy - s:cy, cx - s:cx] = 40
        img[cy:cy + s, cx:cx + s] = 40
        img[cy - s:cy, cx:cx + s] = 235
        img[cy:cy + s, cx - s:cx] = 235
    yy, xx = np.mgrid[:size, :size]
    for _ in range(3):
        x, y, r = rng.integers(20, size - 20), rng.integers(20, size - 20), rng.integers(4, 9)
        img[(xx - x) ** 2 + (yy - y) ** 2 < r * r] = 95
    return np.dstack([img, img, img])


def room(sb: SceneBuilder) -> None:
    """8x8 m room, 3 m high: 7 patches per wall at 3 heights (84), 4 occluding pillars.

    Landmark patches are 0.7 m wide, faded to the wall gray, and 1.1 m apart."""
    half, height, t = 4.0, 3.0, 0.1
    sb.box((0, 0, -t), (half, half, t), material="floor")
    for axis in range(2):
        for sign in (-1, 1):
            pos, normal = np.array([0.0, 0.0, height / 2]), np.zeros(3)
            pos[axis], normal[axis] = sign * half, -sign
            sb.wall(pos, normal, half, height / 2)
    heights = (0.75, 1.55, 2.35)
    along = np.linspace(-half + 0.7, half - 0.7, 7)
    for axis in range(2):
        for sign in (-1, 1):
            normal = np.zeros(3)
            normal[axis] = -sign
            for z in heights:
                for a in along:
                    c = np.zeros(3)
                    c[axis] = sign * (half - OFFSET)
                    c[1 - axis] = a
                    c[2] = z
                    sb.landmark(c, normal)
    for x, y in ((1.9, 1.9), (-1.9, 1.9), (-1.9, -1.9), (1.9, -1.9)):
        sb.cylinder((x, y, height / 2), 0.22, height / 2, "0.75 0.55 0.35 1")


def checkerboard(sb: SceneBuilder) -> None:
    """A 14x7 checkerboard of 0.4 m cells; its 78 inner X-junctions are a lattice of landmarks.

    Only geometry can tell them apart: with pose errors near the 0.4 m spacing the problem is
    ambiguous by construction."""
    t = 0.1
    sb.box((0, 0, -t), (4, 4, t), material="floor")
    sb.wall((0, 3.0, 1.5), (0, -1, 0), 4.0, 1.5)
    cols, rows, cell = BOARD_CELLS[0], BOARD_CELLS[1], BOARD_CELL
    center = np.array([0.0, 3.0 - OFFSET, 0.25 + rows * cell / 2])
    sb.geoms.append(
        f'    <geom type="plane" pos="{_v(center)}" xyaxes="1 0 0 0 0 1" '
        f'size="{cols * cell / 2:.4f} {rows * cell / 2:.4f} {PLANE_GRID}" material="board"/>'
    )
    for r in range(1, rows):
        for c in range(1, cols):
            x = center[0] + (c - cols / 2) * cell
            z = center[2] + (r - rows / 2) * cell
            sb.add_site((x, center[1], z), (0, -1, 0))


def corridor(sb: SceneBuilder) -> None:
    """20 m corridor, 2.4 m wide: patches every 1 m on both walls at two heights (80).

    Made for forward motion (the default trajectory is a line along it)."""
    t, half_w, length, height = 0.1, 1.2, 20.0, 2.6
    sb.box((length / 2, 0, -t), (length / 2 + 1, half_w + 2 * t, t), material="floor")
    for sign in (-1, 1):
        sb.wall((length / 2, sign * half_w, height / 2), (0, -sign, 0), length / 2 + 1, height / 2)
    sb.wall((length + 1, 0, height / 2), (-1, 0, 0), half_w, height / 2)
    for sign in (-1, 1):
        y = sign * (half_w - OFFSET)
        for z in (0.8, 1.8):
            for x in np.arange(1.0, length + 0.01, 1.0):
                sb.landmark((x + (0.5 if z > 1 else 0.0), y, z), (0, -sign, 0), size=0.6)


HALL_VERTICES = ((4.2, 0.0), (2.1, 3.1), (-1.9, 3.4), (-4.0, 0.4), (-2.3, -3.3), (1.8, -3.2))


def polygon_hall(sb: SceneBuilder, vertices=HALL_VERTICES, height: float = 3.0, oriented: bool = False,
                 tiles: bool = False) -> None:
    """A hall whose walls join the ``vertices`` (x, y) of a convex polygon, counterclockwise: the
    default hexagon meets at 105-135° corners. Patches 1.1 m apart at two heights on every wall,
    their sites un-oriented unless ``oriented`` (a user scene's common form; not shipped); with
    ``tiles`` each patch is four 1 cm box tiles on the wall, the site on their shared corner."""
    v = np.asarray(vertices, float)
    lo, hi = v.min(axis=0) - 0.5, v.max(axis=0) + 0.5
    sb.box(((lo + hi) / 2).tolist() + [-0.1], ((hi - lo) / 2).tolist() + [0.1], material="floor")
    for a, b in zip(v, np.roll(v, -1, axis=0)):
        edge = b - a
        length = float(np.linalg.norm(edge))
        inward = np.array([-edge[1], edge[0], 0.0]) / length   # left of a counterclockwise edge
        mid = np.array([*(a + b) / 2, height / 2])
        sb.wall(mid, inward, length / 2 + 0.15, height / 2)      # overlap closes the corners
        k = int((length - 1.2) // 1.1)   # gaps of 1.1 m that fit with 0.6 m clear of the corners
        for s in (np.arange(k + 1) - k / 2) * 1.1:
            for z in (0.9, 1.8):
                c = mid + s * np.array([*edge / length, 0.0])
                c[2] = z
                if tiles:
                    sb.tile_patch(c + 0.01 * inward, inward, size=0.24, thickness=0.01, oriented=oriented)
                else:
                    sb.landmark(c + OFFSET * inward, inward, size=0.6, oriented=oriented)


SCENES = {"room": room, "checkerboard": checkerboard, "corridor": corridor}


def write_textures(out_dir: Path) -> None:
    """Write the wall, landmark and board textures the scenes' MJCF refers to."""
    import cv2

    out_dir.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out_dir / "wall_tile.png"), wall_tile())
    cv2.imwrite(str(out_dir / "landmark.png"), landmark_patch())
    cv2.imwrite(str(out_dir / "board.png"), board_texture())


def write_scene(out_dir: Path, name: str, build, builder: SceneBuilder | None = None,
                **kwargs) -> tuple[Path, SceneBuilder]:
    """Build one scene with ``build(sb, **kwargs)`` into ``builder`` (a fresh ``SceneBuilder(name)``
    when None), write it and its textures into ``out_dir``."""
    write_textures(out_dir)
    sb = builder or SceneBuilder(name)
    build(sb, **kwargs)
    path = out_dir / f"{name}.xml"
    path.write_text(sb.xml((build.__doc__ or name).strip()))
    return path, sb


def generate(out_dir: Path) -> dict[str, int]:
    """Write every scene's MJCF and the wall texture into ``out_dir``; return landmark counts."""
    return {name: write_scene(out_dir, name, build)[1].n_landmarks for name, build in SCENES.items()}


if __name__ == "__main__":
    target = Path(sys.argv[1] if len(sys.argv) > 1 else str(SCENES_DIR))
    for scene, n in generate(target).items():
        print(f"{scene}: {n} landmarks")
