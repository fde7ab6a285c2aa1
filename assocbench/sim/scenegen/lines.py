"""Generator of the lines track's shipped scenes (``assocbench/scenes/office.xml``, ``hallway.xml``,
``furnished.xml``).

Rebuild them with ``python -m assocbench.sim.scenegen.lines``. Map walls are upright box
geoms named ``lw###``, ``WALL_HALF_THICKNESS`` thick and 1.2 m tall (a lidar at 0.5 m sees them);
furniture (boxes and cylinders never named ``lw*``) is clutter. Each scene's scripted loop
(``planar_trajectory.SCENE_PATHS``) is checked to keep ``CLEARANCE`` from every obstacle.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..planar_trajectory import CLEARANCE, SCENE_PATHS
from . import SCENES_DIR
from .planar import WALL_HALF_HEIGHT, WALL_HALF_THICKNESS, floor_scene_xml

WALL_RGBA = "0.75 0.73 0.70 1"
WOOD_RGBA = "0.55 0.38 0.22 1"
FABRIC_RGBA = "0.30 0.40 0.60 1"


@dataclass
class LineBuilder:
    """Accumulates the geoms of one lines scene."""

    name: str
    geoms: list[str] = field(default_factory=list)
    n_walls: int = 0
    n_clutter: int = 0

    def wall(self, x0: float, y0: float, x1: float, y1: float, t: float = WALL_HALF_THICKNESS) -> None:
        """A map wall whose centre line runs from ``(x0, y0)`` to ``(x1, y1)``, ``2t`` thick."""
        c, d = np.array([x0 + x1, y0 + y1]) / 2, np.array([x1 - x0, y1 - y0])
        yaw = np.rad2deg(np.arctan2(d[1], d[0]))
        euler = f' euler="0 0 {yaw:.4f}"' if abs(yaw) > 1e-9 else ""
        self.geoms.append(f'    <geom name="lw{self.n_walls:03d}" type="box" pos="{c[0]:.4f} {c[1]:.4f} '
                          f'{WALL_HALF_HEIGHT}"{euler} size="{np.linalg.norm(d) / 2:.4f} {t:.4f} '
                          f'{WALL_HALF_HEIGHT}" rgba="{WALL_RGBA}"/>')
        self.n_walls += 1

    def room(self, x0: float, x1: float, y0: float, y1: float) -> None:
        """Four walls whose inner faces bound ``[x0, x1] × [y0, y1]`` (corners overlap)."""
        t = WALL_HALF_THICKNESS
        self.wall(x0 - 2 * t, y0 - t, x1 + 2 * t, y0 - t)
        self.wall(x0 - 2 * t, y1 + t, x1 + 2 * t, y1 + t)
        self.wall(x0 - t, y0, x0 - t, y1)
        self.wall(x1 + t, y0, x1 + t, y1)

    def box(self, kind: str, x: float, y: float, hx: float, hy: float, hz: float, yaw_deg: float = 0.0,
            rgba: str = WOOD_RGBA) -> None:
        """Clutter: a box standing on the floor, ``kind`` names it (never ``lw*``)."""
        self.geoms.append(f'    <geom name="{kind}{self.n_clutter:02d}" type="box" pos="{x:.4f} {y:.4f} {hz:.4f}" '
                          f'euler="0 0 {yaw_deg:.3f}" size="{hx:.3f} {hy:.3f} {hz:.3f}" rgba="{rgba}"/>')
        self.n_clutter += 1

    def cylinder(self, kind: str, x: float, y: float, radius: float, hz: float, rgba: str = WOOD_RGBA) -> None:
        """Clutter: an upright cylinder standing on the floor."""
        self.geoms.append(f'    <geom name="{kind}{self.n_clutter:02d}" type="cylinder" pos="{x:.4f} {y:.4f} '
                          f'{hz:.4f}" size="{radius:.3f} {hz:.3f}" rgba="{rgba}"/>')
        self.n_clutter += 1

    def xml(self, comment: str) -> str:
        return floor_scene_xml(self.name, comment, "scenegen.lines",
                               "Map walls: upright box geoms named lw* (their four side faces are the map's lines); every\n"
                               "     other geom is clutter.", self.geoms)


def wall_with_doors(b: LineBuilder, fixed: float, lo: float, hi: float, doors: list[tuple[float, float]],
                    vertical: bool) -> None:
    """A straight wall along x (``vertical``: along y) at ``fixed``, from ``lo`` to ``hi``, with
    gaps ``(start, end)`` for doors."""
    cuts = [lo] + [v for door in sorted(doors) for v in door] + [hi]
    for a, c in zip(cuts[::2], cuts[1::2]):
        b.wall(fixed, a, fixed, c) if vertical else b.wall(a, fixed, c, fixed)


def office(b: LineBuilder) -> None:
    """Office: four rooms in 12 m x 10 m joined by four 1.4 m doors, desks and a cabinet as
    clutter; a loop through every room and door (two laps)."""
    t = WALL_HALF_THICKNESS
    b.room(-6.0, 6.0, -5.0, 5.0)
    wall_with_doors(b, 0.5, -6.0 - t, 6.0 + t, [(-3.7, -2.3), (2.8, 4.2)], vertical=False)
    wall_with_doors(b, -1.0, -5.0, 0.5 - t, [(-3.2, -1.8)], vertical=True)
    wall_with_doors(b, 1.5, 0.5 + t, 5.0, [(2.3, 3.7)], vertical=True)
    b.wall(-6.0, 2.0, -5.0, 2.0)              # a stub wall in the upper-left room
    b.box("desk", -3.5, -4.6, 0.7, 0.35, 0.375)
    b.box("desk", 5.6, 3.0, 0.35, 0.6, 0.375)
    b.box("cabinet", -1.0, 4.65, 0.5, 0.25, 0.6, rgba=FABRIC_RGBA)
    b.box("desk", 3.0, -4.6, 0.7, 0.35, 0.375)


def hallway(b: LineBuilder) -> None:
    """Hallway: a 30 m x 2.5 m corridor, doorways every 5 m on both sides (staggered) into 2 m x 1.5 m
    recesses, pillars along both walls between them (many parallel look-alike lines); a loop
    down one lane and back along the other."""
    t, half, depth = WALL_HALF_THICKNESS, 1.25, 1.5
    doors = {1: [(c - 0.5, c + 0.5) for c in np.arange(-12.5, 12.6, 5.0)],
             -1: [(c - 0.5, c + 0.5) for c in np.arange(-10.0, 10.1, 5.0)]}
    for side, gaps in doors.items():
        wall_with_doors(b, side * (half + t), -15.0 - 2 * t, 15.0 + 2 * t, gaps, vertical=False)
        for a, c in gaps:                      # a recess behind each doorway
            back = side * (half + 2 * t + depth + t)
            b.wall(a - 0.5 - t, back, c + 0.5 + t, back)
            b.wall(a - 0.5 - t, side * (half + 2 * t), a - 0.5 - t, back)
            b.wall(c + 0.5 + t, side * (half + 2 * t), c + 0.5 + t, back)
        for x in np.arange(-10.0, 10.1, 5.0) if side == 1 else np.arange(-12.5, 12.6, 5.0):
            b.wall(x - 0.2, side * (half - 0.125), x + 0.2, side * (half - 0.125), t=0.125)   # a pillar
    b.wall(-15.0 - t, -half, -15.0 - t, half)
    b.wall(15.0 + t, -half, 15.0 + t, half)


def furnished(b: LineBuilder) -> None:
    """Furnished room: 8 m x 6 m with a dining table and four chairs, shelves, a sofa, an
    armchair, a side table and a plant as clutter (short segments that are no map lines); a loop
    around the table (four laps)."""
    b.room(-4.0, 4.0, -3.0, 3.0)
    b.box("table", 0.0, 0.0, 0.8, 0.45, 0.375)
    for x in (-0.45, 0.45):
        for y in (-0.78, 0.78):
            b.box("chair", x, y, 0.22, 0.22, 0.45, rgba=FABRIC_RGBA)
    b.box("shelf", -2.0, 2.78, 0.6, 0.2, 0.9)
    b.box("shelf", 3.78, 0.5, 0.2, 0.7, 0.9)
    b.box("sofa", 1.5, -2.62, 0.9, 0.35, 0.4, rgba=FABRIC_RGBA)
    b.box("armchair", -3.45, 0.3, 0.4, 0.4, 0.45, yaw_deg=15.0, rgba=FABRIC_RGBA)
    b.cylinder("sidetable", -3.4, -2.4, 0.3, 0.35)
    b.cylinder("plant", 3.5, 2.5, 0.2, 0.5, rgba="0.2 0.55 0.25 1")


LINE_SCENES = {"office": office, "hallway": hallway, "furnished": furnished}


def generate(out_dir: Path) -> dict[str, int]:
    """Write every lines scene's MJCF into ``out_dir``; return wall counts. Refuses (AssertionError)
    a scene whose scripted loop comes within ``CLEARANCE`` of an obstacle."""
    from ..line_scene import load_line_scene

    out_dir.mkdir(parents=True, exist_ok=True)
    counts = {}
    for name, build in LINE_SCENES.items():
        b = LineBuilder(name)
        build(b)
        path = out_dir / f"{name}.xml"
        path.write_text(b.xml(" ".join((build.__doc__ or name).split())))
        gap = load_line_scene(path).clearance(SCENE_PATHS[name](np.linspace(0, 2 * np.pi, 4000))).min()
        assert gap >= CLEARANCE, f"{name}: the loop comes {gap:.3f} m from an obstacle"
        counts[name] = b.n_walls
    return counts


if __name__ == "__main__":
    for scene, n in generate(Path(sys.argv[1] if len(sys.argv) > 1 else str(SCENES_DIR))).items():
        print(f"{scene}: {n} walls")
