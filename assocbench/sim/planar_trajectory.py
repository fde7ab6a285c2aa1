"""Scripted robot paths for the planar track: closed loops at constant speed.

A closed curve ``c(t)``, ``t ∈ [0, 2π)``, is re-parametrised by arc length; frame ``k`` of ``N``
sits at ``s_k = (start + laps · k / N) · L``, so the robot drives ``laps`` laps at a constant step
and every landmark seen at the start is revisited after a long excursion. The heading is the
tangent's direction, ``θ = atan2(ċ_y, ċ_x)``. Shipped scenes have their own loop; a user MJCF gets
an ellipse around its anchors, the largest of a few sizes keeping ``CLEARANCE`` from every obstacle,
or a one-line error pointing to ``waypoints`` (``robot_waypoints``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..errors import UserError
from ..models.range_bearing import wrap
from ..validation import check_number
from .footprint import CLEARANCE
from .robot_waypoints import robot_path

if TYPE_CHECKING:
    from .line_scene import LineScene
    from .planar_scene import PlanarScene

DENSE = 4000         # samples of one lap before re-parametrising by arc length

Curve = Callable[[np.ndarray], np.ndarray]   # t (M,) -> points (M, 2)


def park_curve(t: np.ndarray) -> np.ndarray:
    """A wavy ring ``ρ(t) = 6 + 1.5 sin 3t`` (4.5 to 7.5 m from the park's centre), ~42 m a lap."""
    rho = 6.0 + 1.5 * np.sin(3.0 * t)
    return np.column_stack([rho * np.cos(t), rho * np.sin(t)])


def rounded_rectangle(half_x: float, half_y: float, corner: float) -> Curve:
    """A rectangle of half sizes ``half_x × half_y`` at the origin with corners of radius
    ``corner``, counter-clockwise from ``(half_x, 0)``; ``t`` in proportion to arc length."""
    sx, sy = half_x - corner, half_y - corner
    legs = np.array([2 * sy, np.pi * corner / 2, 2 * sx, np.pi * corner / 2] * 2)
    ends = np.cumsum(legs)

    def curve(t: np.ndarray) -> np.ndarray:
        s = (np.asarray(t) / (2 * np.pi) * ends[-1] + sy) % ends[-1]   # start mid right side
        out = np.empty((len(s), 2))
        for i, (x0, y0, dx, dy, arc) in enumerate(_rect_pieces(sx, sy, corner)):
            lo = ends[i - 1] if i else 0.0
            m = (s >= lo) & (s <= ends[i])
            u = s[m] - lo
            if arc is None:
                out[m] = np.column_stack([x0 + dx * u, y0 + dy * u])
            else:
                a = arc + u / corner
                out[m] = np.column_stack([x0 + corner * np.cos(a), y0 + corner * np.sin(a)])
        return out

    return curve


def _rect_pieces(sx: float, sy: float, c: float) -> list[tuple]:
    """Straight legs ``(x0, y0, dx, dy, None)`` and corner arcs ``(cx, cy, 0, 0, a0)`` of a
    rectangle with corners of radius ``c`` at ``(±sx, ±sy)``."""
    h = np.pi / 2
    return [(sx + c, -sy, 0, 1, None), (sx, sy, 0, 0, 0.0), (sx, sy + c, -1, 0, None), (-sx, sy, 0, 0, h),
            (-sx - c, sy, 0, -1, None), (-sx, -sy, 0, 0, 2 * h), (-sx, -sy - c, 1, 0, None),
            (sx, -sy, 0, 0, 3 * h)]


def rounded_polygon(vertices: list[tuple[float, float]], radius: float) -> Curve:
    """The closed polygon through ``vertices`` with each corner an arc of ``radius`` tangent to both
    legs (from ``radius · tan(φ/2)`` before it), from the middle of the first leg; ``t`` by arc
    length. ValueError when a leg is too short for its two arcs."""
    v = np.asarray(vertices, float)
    d = np.roll(v, -1, axis=0) - v                               # leg i: vertex i -> i + 1
    legs = np.linalg.norm(d, axis=1)
    u = d / legs[:, None]
    u_in = np.roll(u, 1, axis=0)                                 # the leg arriving at vertex i
    turn = np.arctan2(u_in[:, 0] * u[:, 1] - u_in[:, 1] * u[:, 0], np.einsum("ij,ij->i", u_in, u))
    cut = radius * np.tan(np.abs(turn) / 2)
    if np.any(legs < cut + np.roll(cut, -1) + 1e-9):
        raise ValueError("rounded_polygon: a leg is shorter than its corners' arcs (smaller radius or longer legs)")
    pieces = []   # (length, point(u) for u in [0, length])
    for i in range(len(v)):
        a = v[i] - u_in[i] * cut[i]
        side = np.sign(turn[i]) or 1.0
        centre = a + side * radius * np.array([-u_in[i, 1], u_in[i, 0]])
        a0 = np.arctan2(*(a - centre)[::-1])
        pieces.append((radius * abs(turn[i]), lambda w, c=centre, a0=a0, s=side: c + radius * np.column_stack(
            [np.cos(a0 + s * w / radius), np.sin(a0 + s * w / radius)])))
        b = v[i] + u[i] * cut[i]
        pieces.append((legs[i] - cut[i] - cut[(i + 1) % len(v)], lambda w, b=b, e=u[i]: b + w[:, None] * e))
    pieces = pieces[1:] + pieces[:1]
    lengths = np.array([p[0] for p in pieces])
    ends = np.cumsum(lengths)
    offset = lengths[0] / 2                                        # start mid first leg

    def curve(t: np.ndarray) -> np.ndarray:
        s = (np.asarray(t) / (2 * np.pi) * ends[-1] + offset) % ends[-1]
        k = np.minimum(np.searchsorted(ends, s, side="right"), len(pieces) - 1)
        out = np.empty((len(s), 2))
        for i in np.unique(k):
            m = k == i
            out[m] = pieces[i][1](s[m] - (ends[i] - lengths[i]))
        return out

    return curve


def _shift_x(curve: Curve, dx: float) -> Curve:
    return lambda t: curve(t) + np.array([dx, 0.0])


# Paths of the shipped scenes (the scene generator keeps every obstacle CLEARANCE away from them)
SCENE_PATHS: dict[str, Curve] = {
    "park": park_curve,
    "post_grid": rounded_rectangle(4.0, 4.0, 1.0),            # through the gaps at x, y = ±4
    "colonnade": _shift_x(rounded_rectangle(11.6, 0.6, 0.6), 11.0),  # lanes y = ±0.6, x 0..22
    # lines track: through the office's four rooms and doors, down the hallway and back, around
    # the furnished room's table
    "office": rounded_polygon([(0.5, -2.5), (-4.7, -2.5), (-4.7, -0.9), (-3.0, -0.9), (-3.0, 2.0), (-4.5, 3.6),
                               (0.0, 3.0), (3.5, 3.0), (3.5, -1.0), (5.0, -3.7)], 0.6),
    "hallway": rounded_rectangle(14.0, 0.4, 0.4),              # lanes y = ±0.4, x −14..14
    "furnished": rounded_rectangle(2.3, 1.6, 0.8),
}
DEFAULT_LAPS = {"park": 2, "post_grid": 2, "colonnade": 1, "office": 2, "hallway": 1, "furnished": 4}
FULL_RUN = 500   # frames in which a shipped path's default laps are driven; fewer frames drive part of it
# colonnade starts at x = 0 on the lower lane heading +x (the lap starts mid right U-turn)
# the hallway starts at its west end on the lower lane heading +x
DEFAULT_START = {"colonnade": (22.0 + 1.5 * np.pi * 0.6) / (44.0 + 2 * np.pi * 0.6),
                 "hallway": (27.2 + 1.5 * np.pi * 0.4) / (54.4 + 2 * np.pi * 0.4)}
TRAJECTORIES = ("loop", "ellipse", "waypoints")   # the scene's own path; around the posts; the user's file
PARAMS = {"loop": ("laps", "start"), "ellipse": ("laps", "start", "scale"), "waypoints": ("file",)}
# how to give a path of one's own, for the messages that refuse another
OWN_PATH = ("give the robot's own path: --trajectory waypoints --set trajectory_params.file=path.csv, a CSV "
            "with the header 'x,y' and one waypoint (m) a line, e.g. '0,0', '3,0', '3,2' (docs: the planar "
            "and lines track pages)")


def resample(curve: Curve, laps: float, frames: int, start: float = 0.0) -> np.ndarray:
    """Poses (frames, 3) at equal arc-length steps, ``s_k = (start + laps k / N) L``, ``θ_k`` the
    tangent."""
    t = np.linspace(0.0, 2 * np.pi, DENSE + 1)
    pts = curve(t)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = s[-1]
    heading = np.unwrap(np.arctan2(*np.diff(pts, axis=0).T[::-1]))
    mid = (s[:-1] + s[1:]) / 2
    sk = ((start + laps * np.arange(frames) / frames) % 1.0) * length
    x, y = np.interp(sk, s, pts[:, 0]), np.interp(sk, s, pts[:, 1])
    th = np.interp(sk, mid, heading)
    return np.column_stack([x, y, wrap(th)])


def ellipse_curve(scene: PlanarScene | LineScene, scale: float, shift: np.ndarray | None = None) -> Curve:
    """An ellipse on the anchors' principal axes around their centroid (shifted by ``shift`` × the
    semi-axes), semi-axes ``scale ×`` √2 × their standard deviation (at least 0.7 m). Anchors:
    posts, or wall-face midpoints."""
    shift = np.zeros(2) if shift is None else shift
    anchors = scene.anchors
    centre = anchors.mean(axis=0)
    cov = np.cov((anchors - centre).T) if len(anchors) > 1 else np.eye(2)
    w, v = np.linalg.eigh(np.atleast_2d(cov))
    axes = scale * np.sqrt(2 * np.maximum(w, 0.25))
    centre = centre + v @ (axes * shift)
    return lambda t: centre + (np.column_stack([axes[0] * np.cos(t), axes[1] * np.sin(t)]) @ v.T)


SHIFTS = sorted(((a, b) for a in np.linspace(-0.3, 0.3, 5) for b in np.linspace(-0.3, 0.3, 5)),
                key=lambda ab: (np.hypot(*ab), ab))


def default_ellipse(scene: PlanarScene | LineScene, laps: float, frames: int, start: float) -> np.ndarray:
    """The first ellipse (largest scale, smallest shift first) keeping ``CLEARANCE`` from every
    obstacle; a one-line error when none does."""
    for scale in np.linspace(1.2, 0.3, 10):
        for shift in SHIFTS:
            curve = ellipse_curve(scene, scale, np.array(shift))
            if scene.clearance(curve(np.linspace(0, 2 * np.pi, 400))).min() >= CLEARANCE:
                return resample(curve, laps, frames, start)
    raise UserError(f"no collision-free default loop in {scene.path.name}: no ellipse around the {_what(scene)} keeps "
                    f"{CLEARANCE} m from every obstacle; "
                    + ("use trajectory 'loop', the scene's own path, or " if scripted(scene.path) else "")
                    + OWN_PATH)


def _what(scene) -> str:
    """What a scene's anchors are, for messages."""
    return "posts" if hasattr(scene, "posts") else "walls"


def _params(name: str, params: dict) -> tuple[float, float, float]:
    """(laps, start, scale) from user parameters, each checked (one-line errors)."""
    for key in params:
        if key not in PARAMS[name]:
            hint = "; a waypoint file needs --trajectory waypoints (trajectory: waypoints)" if key == "file" else ""
            raise UserError(f"trajectory {name!r} takes no parameter {key!r}; it takes {', '.join(PARAMS[name])}{hint}")
    laps = check_number(params.get("laps", 1), "trajectory_params.laps", lo=0, hi=100, lo_open=True)
    start = check_number(params.get("start", 0.0), "trajectory_params.start", lo=0, hi=1, hi_open=True)
    scale = check_number(params.get("scale", 1.0), "trajectory_params.scale", lo=0, hi=10, lo_open=True)
    return float(laps), float(start), float(scale)


def planar_trajectory(scene: PlanarScene | LineScene, name: str | None, frames: int, seed: int = 0,
                      **params) -> np.ndarray:
    """Robot poses ``(frames, 3)``: ``loop`` (a shipped scene's path), ``ellipse`` (around the
    posts; a user MJCF's default) or ``waypoints`` (``robot_waypoints``). ``seed`` changes nothing
    (common signature)."""
    del seed
    own = scripted(scene.path)
    name = name or ("loop" if own else "ellipse")
    if name not in TRAJECTORIES:
        raise UserError(f"unknown planar trajectory {name!r}: choose one of {', '.join(TRAJECTORIES)}")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise UserError(f"frames must be a positive integer, got {frames!r}")
    if name == "waypoints":
        return robot_path(scene, params, frames)
    # the robot's speed is the scene's (its laps in FULL_RUN frames: 0.10-0.17 m a frame), so a
    # short run drives part of the loop rather than the whole loop in strides odometry cannot follow
    laps = DEFAULT_LAPS.get(scene.name, 1) * min(1.0, frames / FULL_RUN)
    defaults = {"laps": laps, "start": DEFAULT_START.get(scene.name, 0.0)} if own else {"laps": laps}
    params = defaults | params
    laps, start, scale = _params(name, params)
    if name == "loop":
        if not own:
            raise UserError(f"scene {scene.name!r} has no scripted loop (loops exist for {', '.join(SCENE_PATHS)}): "
                            f"use trajectory 'ellipse', or {OWN_PATH}")
        return resample(SCENE_PATHS[scene.name], laps, frames, start)
    if "scale" in params:
        curve = ellipse_curve(scene, scale)
        if scene.clearance(curve(np.linspace(0, 2 * np.pi, 400))).min() < CLEARANCE:
            raise UserError(f"trajectory_params.scale {scale} drives the robot within {CLEARANCE} m of an obstacle in "
                            f"{scene.path.name}; pick another scale, leave it out (the default ellipse keeps clear) "
                            f"or {OWN_PATH}")
        return resample(curve, laps, frames, start)
    return default_ellipse(scene, laps, frames, start)


def scripted(path) -> bool:
    """Whether the scene at ``path`` is a shipped one with its own scripted ``loop``."""
    return path.stem in SCENE_PATHS and path.parent == _shipped_dir()


def _shipped_dir():
    from .scene import shipped_scenes

    return next(iter(shipped_scenes().values())).parent
