"""Write the learned associator's training scenes for the planar and lines tracks into
examples/learned/scenes/: scenes no leaderboard suite uses, so the shipped planar and lines
models are never trained on a scene they are scored on.

Each scene leaves a ring-shaped lane free around its centre, where the default ``ellipse``
trajectory of a user MJCF drives (the robot circles the scene, seeing posts or walls on both
sides):

    python examples/learned/make_lidar_scenes.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from assocbench.sim.scenegen.lines import LineBuilder, wall_with_doors
from assocbench.sim.scenegen.planar import POST_RADIUS, PlanarBuilder

LANE_RADIUS, LANE_HALF_WIDTH = 5.0, 1.4   # m: the free ring the robot's loop lies in


def in_lane(p: np.ndarray) -> bool:
    return abs(np.hypot(*p) - LANE_RADIUS) < LANE_HALF_WIDTH + POST_RADIUS


def orchard(b: PlanarBuilder) -> None:
    """Orchard: 42 random posts in 16 m x 16 m (another draw than the park's), a few clutter
    boxes and cylinders, a free ring lane of radius 5 m."""
    rng = np.random.default_rng(1030)
    posts: list[np.ndarray] = []
    while len(posts) < 42:
        p = rng.uniform(-7.8, 7.8, 2)
        if not in_lane(p) and (not posts or np.min(np.linalg.norm(np.array(posts) - p, axis=1)) >= 1.2):
            posts.append(p)
    for x, y in posts:
        b.post(x, y)
    for x, y, hx, hy, yaw in ((0.0, 1.2, 0.4, 0.3, 0.4), (7.2, -7.3, 0.3, 0.5, 0.0), (-7.4, 6.9, 0.5, 0.3, 1.0)):
        b.clutter_box(x, y, hx, hy, yaw)
    for x, y in ((-1.3, -1.0), (7.3, 7.2)):
        b.clutter_cylinder(x, y)
    b.walls(-8.6, 8.6, -8.6, 8.6)


def lattice(b: PlanarBuilder) -> None:
    """Lattice: a triangular lattice of posts 1.9 m apart (geometric ambiguity, another pattern
    than the post grid's squares), a free ring lane of radius 5 m."""
    for row, y in enumerate(np.arange(-7.6, 7.7, 1.9 * np.sqrt(3) / 2)):
        for x in np.arange(-7.6 + (row % 2) * 0.95, 7.7, 1.9):
            if not in_lane(np.array([x, y])):
                b.post(x, y)
    for x, y in ((8.3, 0.0), (-8.3, 4.0)):
        b.clutter_cylinder(x, y)
    b.walls(-8.9, 8.9, -8.9, 8.9)


def cloister(b: LineBuilder) -> None:
    """Cloister: a 14 m x 11 m hall around a 5 m x 3 m inner block, buttresses along the outer
    walls (parallel look-alike faces), a bench and two planters as clutter."""
    b.room(-7.0, 7.0, -5.5, 5.5)
    for x0, x1, y0, y1 in ((-2.5, 2.5, -1.5, -1.5), (-2.5, 2.5, 1.5, 1.5), (-2.5, -2.5, -1.5, 1.5),
                           (2.5, 2.5, -1.5, 1.5)):
        b.wall(x0, y0, x1, y1)
    for x in (-4.5, -1.5, 1.5, 4.5):
        for side in (-1, 1):
            b.wall(x - 0.25, side * 5.3, x + 0.25, side * 5.3, t=0.15)
    b.box("bench", 0.0, -4.8, 0.8, 0.2, 0.25)
    b.cylinder("planter", -6.4, 4.9, 0.3, 0.4)
    b.cylinder("planter", 6.4, -4.9, 0.3, 0.4)


def gallery(b: LineBuilder) -> None:
    """Gallery: a 16 m x 9 m room split by a central partition with two gaps, pilasters along the
    long walls; plinths as clutter."""
    b.room(-8.0, 8.0, -4.5, 4.5)
    wall_with_doors(b, 0.0, -4.0, 4.0, [(-1.0, -0.2), (0.2, 1.0)], vertical=False)
    for x in (-6.0, -3.0, 3.0, 6.0):
        for side in (-1, 1):
            b.wall(x - 0.3, side * 4.3, x + 0.3, side * 4.3, t=0.2)   # a pilaster
    b.box("plinth", -7.4, 0.0, 0.25, 0.25, 0.5)
    b.box("plinth", 7.4, 0.0, 0.25, 0.25, 0.5)


PLANAR = {"orchard": orchard, "lattice": lattice}
LINES = {"cloister": cloister, "gallery": gallery}


def main(out: Path = Path(__file__).parent / "scenes") -> None:
    from assocbench.sim.line_scene import load_line_scene
    from assocbench.sim.planar_scene import load_planar_scene
    from assocbench.sim.planar_trajectory import planar_trajectory

    out.mkdir(parents=True, exist_ok=True)
    for builders, make, load, what in ((PLANAR, PlanarBuilder, load_planar_scene, "posts"),
                                       (LINES, LineBuilder, load_line_scene, "walls")):
        for name, build in builders.items():
            b = make(name)
            build(b)
            path = out / f"{name}.xml"
            path.write_text(b.xml(" ".join((build.__doc__ or name).split())))
            planar_trajectory(load(path), None, 500)   # the default loop fits (a one-line error if not)
            print(f"{path}: {b.n_posts if what == 'posts' else b.n_walls} {what}")


if __name__ == "__main__":
    main()
