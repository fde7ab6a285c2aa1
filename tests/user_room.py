"""A user's L-shaped room written by the tests (no shipped scene): six walls, none at a right
angle to the next, twelve posts placed here, and a closed waypoint path through both wings.

``room_mjcf(tmp_path, "planar")`` names the posts ``lm*`` (planar track; the walls are clutter),
``room_mjcf(tmp_path, "lines")`` names the walls ``lw*`` (lines track; the posts are clutter)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# the room's corners, counter-clockwise: a wing 9 m along x and a wing 9 m along y, slanted walls
CORNERS = [(0, 0), (9, 0), (9.6, 3.5), (4.5, 3.8), (4.0, 9.0), (-0.5, 8.5)]
POSTS = [(2.1, 3.5), (2.1, 5.0), (2.1, 6.4), (4.5, 1.9), (6.2, 1.9), (3.0, 0.45), (5.5, 0.5), (8.4, 1.5),
         (5.0, 3.3), (0.45, 4.0), (3.7, 5.5), (1.9, 8.2)]
# a closed loop through both wings, 0.6 m or more from every post and wall (about 25 m)
PATH = [(7.5, 1.2), (1.3, 1.2), (1.2, 7.3), (2.9, 7.3), (3.0, 2.6), (7.5, 2.6), (7.5, 1.2)]
WALL_HALF_THICKNESS = 0.05


def walls(prefix: str) -> list[str]:
    """One box per side of the room, its inner face on the side, turned about z to the side's angle."""
    out = []
    corners = np.array(CORNERS, float)
    for i, a in enumerate(corners):
        b = corners[(i + 1) % len(corners)]
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        centre = (a + b) / 2 + WALL_HALF_THICKNESS * np.array([u[1], -u[0]])   # outwards: the room is on the left
        yaw = np.degrees(np.arctan2(u[1], u[0]))
        out.append(f'<geom name="{prefix}{i}" type="box" pos="{centre[0]:.4f} {centre[1]:.4f} 0.6" '
                   f'euler="0 0 {yaw:.4f}" size="{length / 2 + WALL_HALF_THICKNESS:.4f} {WALL_HALF_THICKNESS} 0.6"/>')
    return out


def room_mjcf(folder: Path, track: str) -> Path:
    """Write the room for ``track`` (``planar``: posts ``lm*``; ``lines``: walls ``lw*``) and return its path."""
    wall, post = ("wall", "lm") if track == "planar" else ("lw", "pillar")
    posts = [f'<geom name="{post}{i}" type="cylinder" pos="{x} {y} 0.5" size="0.1 0.5"/>'
             for i, (x, y) in enumerate(POSTS)]
    path = folder / f"{track}_room.xml"
    path.write_text('<mujoco><worldbody>\n<geom name="floor" type="plane" size="0 0 0.1"/>\n'
                    + "\n".join(walls(wall) + posts) + "\n</worldbody></mujoco>\n")
    return path


def path_csv(folder: Path, points=PATH, name: str = "path.csv") -> Path:
    """Write waypoints ``points`` as a CSV with the header ``x,y``."""
    path = folder / name
    path.write_text("x,y\n" + "".join(f"{x},{y}\n" for x, y in points))
    return path
