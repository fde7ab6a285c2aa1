"""A robot's own path in the plane (planar and lines tracks): waypoints from a CSV or YAML file.

A waypoint file lists positions ``x, y`` (m, world) and optionally a ``heading`` (deg,
counter-clockwise from +x) and a time ``t`` (strictly increasing). The robot drives the polyline
through them; frame ``k`` of ``N`` sits at arc length ``s_k = k / (N − 1) · L``, or with ``t`` at
time ``t_0 + k / (N − 1) · (t_end − t_0)`` (constant speed per leg). Without ``heading`` it faces
along its leg, turning at a constant rate over ``TURN`` m around each waypoint; with it, the heading
is interpolated in arc length, the shorter way round. A closed path ends with its first waypoint.

CSV (a header, ``#`` comments)::

    x, y                  or        x, y, heading
    0, 0                            0, 0, 0
    3, 0                            3, 0, 90

YAML (a list, or a mapping with ``waypoints:``)::

    - {position: [0, 0]}
    - {position: [3, 0], heading: 90, t: 2.0}

Every waypoint must lie within ``MARGIN`` of the scene and every leg ``CLEARANCE`` from every
obstacle, or a one-line error names the waypoint or leg and the obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..models.range_bearing import wrap
from ..validation import brief
from .footprint import CLEARANCE, extent, nearest_obstacle
from .waypoints import csv_table, number, read_text, vector, waypoint_path, yaml_list

HOW = "a CSV or YAML file of the robot's waypoints x, y (m) [, heading (deg)], e.g. the lines 'x,y', '0,0', '3,0'"
TURN = 0.5      # m before and after a waypoint over which the heading turns from one leg to the next
MARGIN = 2.0    # m: a waypoint farther than this outside the rectangle around the obstacles is outside the scene
STEP = 0.02     # m between the points of a leg checked for clearance
COLUMNS = ("x", "y", "heading", "t")


@dataclass(frozen=True)
class RobotWaypoints:
    """Waypoints read from ``path``: positions (W, 2) m, headings (W,) rad or None, times (W,) or
    None, and where each is written, for messages."""

    path: Path
    points: np.ndarray
    headings: np.ndarray | None
    times: np.ndarray | None
    where: tuple[str, ...]

    def name(self, i: int) -> str:
        """Waypoint ``i`` for messages: its number, where it is written and its position."""
        x, y = self.points[i]
        return f"waypoint {i + 1} ({self.where[i]} of {self.path.name}, at x {x:.2f} m, y {y:.2f} m)"


def read_robot_waypoints(path: Path) -> RobotWaypoints:
    """Parse and check a robot waypoint file (at least 2 waypoints, finite numbers, ``heading`` and
    ``t`` for all or none, ``t`` increasing, no repeated waypoint); one-line ``UserError`` naming
    file and line."""
    text = read_text(path)
    rows = _csv_rows(path, text) if path.suffix.lower() == ".csv" else _yaml_rows(path, text)
    if len(rows) < 2:
        raise UserError(f"waypoint file {path} has {len(rows)} waypoint(s); give at least 2 ({HOW})")
    where = tuple(r[0] for r in rows)
    points = np.array([[r[1]["x"], r[1]["y"]] for r in rows])
    optional = {}
    for key in ("heading", "t"):
        given = [key in r[1] for r in rows]
        if any(given) and not all(given):
            raise UserError(f"waypoint file {path}: give {key} for every waypoint or for none "
                            f"({where[given.index(not given[0])]} differs from {where[0]})")
        optional[key] = np.array([r[1][key] for r in rows]) if all(given) else None
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(legs < 1e-6):
        i = int(np.flatnonzero(legs < 1e-6)[0]) + 1
        raise UserError(f"waypoint file {path} {where[i]}: the waypoint repeats the one before it; remove it "
                        f"(the robot turns along its legs)")
    t = optional["t"]
    if t is not None and np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise UserError(f"waypoint file {path} {where[i]}: t must increase strictly ({t[i - 1]:g} then {t[i]:g})")
    heading = optional["heading"]
    return RobotWaypoints(path, points, None if heading is None else np.deg2rad(heading), t, where)


Row = tuple[str, dict[str, float]]   # where it is written, {column: value}


def _csv_rows(path: Path, text: str) -> list[Row]:
    at, header, table = csv_table(path, text)
    if not header:
        return []
    if not {"x", "y"} <= set(header) or not set(header) <= set(COLUMNS) or len(set(header)) != len(header):
        raise UserError(f"waypoint file {path} {at}: the header must name x and y (m; heading in deg and t "
                        f"optional), each once; got {', '.join(header)}")
    return [(where, {h: number(path, where, h, c) for h, c in zip(header, cells)}) for where, cells in table]


def _yaml_rows(path: Path, text: str) -> list[Row]:
    rows = []
    for k, item in enumerate(yaml_list(path, text, "{position: [x, y]} (heading: deg, t optional)")):
        where = f"waypoint {k + 1}"
        if not isinstance(item, dict) or "position" not in item or not set(item) <= {"position", "heading", "t"}:
            raise UserError(f"waypoint file {path} {where}: expected a mapping with position: [x, y] (heading: deg "
                            f"and t optional), got {brief(item)}")
        x, y = vector(path, where, "position", item["position"], "x, y")
        values = {"x": x, "y": y} | {key: number(path, where, key, item[key]) for key in ("heading", "t") if key in item}
        rows.append((where, values))
    return rows


def waypoint_poses(wp: RobotWaypoints, frames: int) -> np.ndarray:
    """Poses (frames, 3) ``(x, y, θ)`` along the polyline through ``wp``: equal arc-length (or, with
    times, equal time) steps, headings as the module says."""
    s_wp = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(wp.points, axis=0), axis=1))])
    share = np.linspace(0.0, 1.0, frames) if frames > 1 else np.zeros(1)
    if wp.times is None:
        s = share * s_wp[-1]
    else:
        s = np.interp(wp.times[0] + share * (wp.times[-1] - wp.times[0]), wp.times, s_wp)
    x, y = np.interp(s, s_wp, wp.points[:, 0]), np.interp(s, s_wp, wp.points[:, 1])
    knots_s, knots_h = (s_wp, _unwrapped(wp.headings)) if wp.headings is not None else _turns(wp.points, s_wp)
    return np.column_stack([x, y, wrap(np.interp(s, knots_s, knots_h))])


def _unwrapped(angles: np.ndarray) -> np.ndarray:
    """``angles`` made continuous: each step the shorter way round, ``θ_0 + Σ wrap(Δθ)``."""
    return angles[0] + np.concatenate([[0.0], np.cumsum(wrap(np.diff(angles)))])


def _turns(points: np.ndarray, s_wp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knots (arc length, unwrapped heading) of a robot facing along each leg and turning over
    ``±d_i`` around waypoint ``i``, ``d_i = min(TURN, ℓ_{i−1}/2, ℓ_i/2)``."""
    d = np.diff(points, axis=0)
    lengths = np.linalg.norm(d, axis=1)
    legs = _unwrapped(np.arctan2(d[:, 1], d[:, 0]))
    knots_s, knots_h = [0.0], [legs[0]]
    for i in range(1, len(points) - 1):
        half = min(TURN, lengths[i - 1] / 2, lengths[i] / 2)
        knots_s += [s_wp[i] - half, s_wp[i] + half]
        knots_h += [legs[i - 1], legs[i]]
    return np.array(knots_s + [s_wp[-1]]), np.array(knots_h + [legs[-1]])


def check_clearance(scene, wp: RobotWaypoints) -> None:
    """Refuse in one line a waypoint more than ``MARGIN`` outside the scene's obstacles' rectangle,
    or a path point closer than ``CLEARANCE`` to an obstacle's footprint."""
    lo, hi = extent(scene)
    outside = np.flatnonzero(np.any((wp.points < lo - MARGIN) | (wp.points > hi + MARGIN), axis=1))
    if len(outside):
        raise UserError(f"{wp.name(outside[0])} is outside the scene {scene.path.name} (its obstacles span x "
                        f"{lo[0]:.2f}..{hi[0]:.2f} m, y {lo[1]:.2f}..{hi[1]:.2f} m; waypoints may lie up to "
                        f"{MARGIN:g} m beyond): move it inside; waypoints are in the scene's world frame, in m")
    dist, geom = nearest_obstacle(scene, wp.points)
    fix = f"the robot keeps {CLEARANCE} m (its 0.3 m radius and a margin) from every obstacle's footprint"
    near = np.flatnonzero(dist < CLEARANCE)
    if len(near):
        i = near[0]
        raise UserError(f"{wp.name(i)} is {dist[i]:.2f} m from {_obstacle(scene, geom[i])}; {fix}: move the waypoint")
    for i in range(len(wp.points) - 1):
        a, b = wp.points[i], wp.points[i + 1]
        u = np.linspace(0.0, 1.0, int(np.ceil(np.linalg.norm(b - a) / STEP)) + 1)
        xy = a + u[:, None] * (b - a)
        dist, geom = nearest_obstacle(scene, xy)
        j = int(np.argmin(dist))
        if dist[j] < CLEARANCE:
            raise UserError(f"the leg from {wp.name(i)} to waypoint {i + 2} passes {dist[j]:.2f} m from "
                            f"{_obstacle(scene, geom[j])} at x {xy[j, 0]:.2f} m, y {xy[j, 1]:.2f} m; {fix}: add a "
                            f"waypoint to steer around it or move one")


def _obstacle(scene, g: int) -> str:
    """Obstacle ``g`` for messages: its name (or number) and where its centre is."""
    m, d = scene.model, scene.data
    name = m.geom(int(g)).name
    x, y = d.geom_xpos[g, :2]
    return f"obstacle {repr(name) if name else f'geom {g}'} (centre x {x:.2f} m, y {y:.2f} m)"


def waypoint_file(params: dict, scene) -> Path:
    """The waypoint file of ``trajectory_params.file`` (as given, else beside the scene's MJCF); no
    other parameter."""
    other = sorted(set(params) - {"file"})
    if other:
        raise UserError(f"trajectory 'waypoints' takes no parameter {other[0]!r}; it takes file ({HOW})")
    return waypoint_path(params, Path(scene.path).parent, HOW)


def robot_path(scene, params: dict, frames: int) -> np.ndarray:
    """Poses (frames, 3) along the waypoints of ``trajectory_params.file``, checked against ``scene``."""
    wp = read_robot_waypoints(waypoint_file(params, scene))
    check_clearance(scene, wp)
    return waypoint_poses(wp, frames)
