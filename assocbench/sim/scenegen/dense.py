"""Generator of the dense track's shipped scenes (``bays.xml``, ``crates.xml``), rebuilt with
``python -m assocbench.sim.scenegen.dense``. Both are self-similar on purpose: ``bays`` is a
corridor whose cross-section repeats every ``BAY_PERIOD`` metres, so a frame fits it shifted by a
period almost as well; ``crates`` is a room of identical boxes on a grid. Boxes and finite planes
only, so the surface error is analytic; the camera scenes' conventions (``lm###`` sites, textured
walls), so the camera track runs on them too. The clip planes are pinned in metres (near ``NEAR_M``,
far ``FAR_M``, outside any depth sensor's range) so the depth buffer keeps sub-millimetre precision
where depth is measured.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from . import SCENES_DIR
from .camera import OFFSET, SceneBuilder, write_scene

EXTENT = 10.0        # m: the pinned model extent MuJoCo scales znear and zfar by
NEAR_M, FAR_M = 0.05, 20.0

# bays: a corridor along +x from 0 to BAY_COUNT * BAY_PERIOD
BAY_PERIOD = 1.5     # m between identical frames (pier pair + beam + sill)
BAY_COUNT = 10       # bays between the 11 frames: a 15 m corridor
HALF_CLEAR = 1.35    # m from the axis to a pier face: 2.7 m clear between piers
RECESS = 0.30        # m a bay's back wall lies behind the pier faces
PIER = 0.40          # m: a frame's length along the corridor
BAY_HEIGHT = 2.5     # m floor to ceiling
BEAM = 0.20          # m a ceiling beam hangs down
SILL = 0.10          # m a floor sill stands up
BAY_PATCH_Z = (0.65, 1.25, 1.85)   # landmark heights on each bay's back wall and each pier's face
BAY_PATCH = 0.5      # m: side of a patch on a bay's back wall
PIER_PATCH = 0.35    # m: side of a patch on a pier's face (0.4 m wide)

# crates: a square room with identical crates on the perimeter of a 5 x 5 grid
ROOM_HALF = 3.0      # m: the room is 6 x 6 m
ROOM_HEIGHT = 2.6
CRATE = 0.6          # m: side of a crate (a cube)
CRATE_GRID = 1.0     # m between neighbouring crates
ROOM_PATCH_Z = (0.8, 1.3, 1.8)   # landmark heights on the walls: with the crates' patches they put the camera
ROOM_PATCH = 0.45                # about 1.1 m up (the rig's height is the landmarks'), low enough to see the crates
CRATE_PATCH = 0.45

PIER_RGBA = "0.59 0.59 0.59 1"   # the wall gray the patches fade to: a patch adds no corners of its own
BEAM_RGBA = "0.7 0.7 0.72 1"
SILL_RGBA = "0.35 0.35 0.38 1"
CEILING_RGBA = "0.85 0.85 0.85 1"
CRATE_RGBA = "0.6 0.45 0.25 1"


def box_between(sb: SceneBuilder, lo, hi, rgba: str | None = None, material: str | None = None) -> None:
    """An axis-aligned box geom filling ``[lo, hi]`` (corners, m)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    sb.box((lo + hi) / 2, (hi - lo) / 2, rgba=rgba or "0.6 0.6 0.6 1", material=material)


def bays(sb: SceneBuilder) -> None:
    """Bays: a 15 m corridor, 2.7 m wide, whose cross-section repeats every 1.5 m (self-similar
    along its axis); 114 landmarks. Made for forward motion (a line along it).

    Each of 11 frames is a pier on each wall, a ceiling beam and a floor sill; between them lie 10
    identical bays recessed 0.3 m into each wall. Checker patches at three heights on each bay's
    back wall and each inner pier's face."""
    length, back = BAY_COUNT * BAY_PERIOD, HALF_CLEAR + RECESS
    t = 0.2   # thickness of the shell (floor, ceiling, end walls)
    box_between(sb, (-t, -back - t, -0.1), (length + t, back + t, 0.0), material="floor")
    box_between(sb, (-t, -back - t, BAY_HEIGHT), (length + t, back + t, BAY_HEIGHT + 0.1), rgba=CEILING_RGBA)
    for x0, x1 in ((-t, 0.0), (length, length + t)):
        box_between(sb, (x0, -back, 0.0), (x1, back, BAY_HEIGHT), rgba=PIER_RGBA)
    for sign in (-1, 1):   # the bays' back walls, textured (planes carry 2D textures, boxes do not)
        sb.wall((length / 2, sign * back, BAY_HEIGHT / 2), (0, -sign, 0), length / 2, BAY_HEIGHT / 2)
    for k in range(BAY_COUNT + 1):   # the end frames stand half inside the end walls
        x0, x1 = k * BAY_PERIOD - PIER / 2, k * BAY_PERIOD + PIER / 2
        for sign in (-1, 1):
            y = sorted((sign * HALF_CLEAR, sign * back))
            box_between(sb, (x0, y[0], 0.0), (x1, y[1], BAY_HEIGHT), rgba=PIER_RGBA)
        box_between(sb, (x0, -HALF_CLEAR, BAY_HEIGHT - BEAM), (x1, HALF_CLEAR, BAY_HEIGHT), rgba=BEAM_RGBA)
        box_between(sb, (x0, -HALF_CLEAR, 0.0), (x1, HALF_CLEAR, SILL), rgba=SILL_RGBA)
    for k in range(BAY_COUNT):   # patches in the recesses: seen from the axis only near the camera
        x = (k + 0.5) * BAY_PERIOD
        for sign in (-1, 1):
            for z in BAY_PATCH_Z:
                sb.landmark((x, sign * (back - OFFSET), z), (0, -sign, 0), size=BAY_PATCH)
    for k in range(1, BAY_COUNT):   # and on the inner piers' faces, seen far down the corridor
        for sign in (-1, 1):
            for z in BAY_PATCH_Z:
                sb.landmark((k * BAY_PERIOD, sign * (HALF_CLEAR - OFFSET), z), (0, -sign, 0), size=PIER_PATCH)


def crate_cells() -> list[tuple[float, float, int]]:
    """(x, y, height in crates) of each stack: the 16 perimeter cells of a 5 x 5 grid ``CRATE_GRID``
    apart, two high, three at the corners (36 crates). Stacks this tall fill a camera's view at 1.1
    m, and their sides seen through the gaps pin the motion along the walls that wall and crate
    fronts alone leave free (ICP's normal matrix is ill conditioned with one-high crates)."""
    cells = []
    for i in range(-2, 3):
        for j in range(-2, 3):
            if max(abs(i), abs(j)) == 2:
                cells.append((i * CRATE_GRID, j * CRATE_GRID, 3 if abs(i) == abs(j) else 2))
    return cells


def crates(sb: SceneBuilder) -> None:
    """Crates: a 6 x 6 m room with 36 identical 0.6 m crates in a square ring; 72 landmarks.

    The crates stand on the perimeter of a 5 x 5 grid 1 m apart, two high, three at its corners; checker
    patches on the faces of the 12 lower crates of the side stacks towards the middle and on the walls, five per
    wall at three heights. The middle is clear for a circle looking outward."""
    h, t = ROOM_HALF, 0.1
    box_between(sb, (-h - t, -h - t, -t), (h + t, h + t, 0.0), material="floor")
    box_between(sb, (-h - t, -h - t, ROOM_HEIGHT), (h + t, h + t, ROOM_HEIGHT + t), rgba=CEILING_RGBA)
    along = np.arange(-2, 3) * 1.0
    for axis in range(2):
        for sign in (-1, 1):
            normal = np.zeros(3)
            normal[axis] = -sign
            center = np.array([0.0, 0.0, ROOM_HEIGHT / 2])
            center[axis] = sign * h
            sb.wall(center, normal, h, ROOM_HEIGHT / 2)
            for a in along:
                for z in ROOM_PATCH_Z:
                    c = np.array([0.0, 0.0, z])
                    c[axis], c[1 - axis] = sign * (h - OFFSET), a
                    sb.landmark(c, normal, size=ROOM_PATCH)
    half = CRATE / 2
    for x, y, stack in crate_cells():
        for level in range(stack):
            sb.box((x, y, half + level * CRATE), (half, half, half), rgba=CRATE_RGBA)
        if abs(x) == abs(y):
            continue   # a corner stack's faces look at its neighbours in the ring: no patch
        axis = 0 if abs(x) > abs(y) else 1   # the face towards the middle
        normal = np.zeros(3)
        normal[axis] = -np.sign((x, y)[axis])
        sb.landmark(np.array([x, y, half]) + (half + OFFSET) * normal, normal, size=CRATE_PATCH)


DENSE_SCENES = {"bays": bays, "crates": crates}


def generate(out_dir: Path) -> dict[str, int]:
    """Write the dense scenes' MJCF (and the shared textures) into ``out_dir``; return landmark counts."""
    counts = {}
    for name, build in DENSE_SCENES.items():
        sb = SceneBuilder(name, generator="scenegen.dense", znear=NEAR_M / EXTENT, zfar=FAR_M / EXTENT,
                          extent=EXTENT)
        counts[name] = write_scene(out_dir, name, build, builder=sb)[1].n_landmarks
    return counts


if __name__ == "__main__":
    for scene, n in generate(Path(sys.argv[1] if len(sys.argv) > 1 else str(SCENES_DIR))).items():
        print(f"{scene}: {n} landmarks")
