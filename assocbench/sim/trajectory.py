"""Named, parameterised, seeded camera trajectories, placed and sized (``radius`` defaults to the
rig's ``motion``) by a *rig* derived from the scene's landmarks, so a user MJCF needs no
configuration: a wall (agreeing normals) is viewed from in front, an enclosure from inside, from the
landmark centroid along its long axis; the scene's free space keeps the camera out of walls,
pillars, floor and ceiling. Or the user's own path: ``waypoints`` or ``mjcf-cameras``
(``Keyframes``). Metres and degrees; ``seed`` sets the start phase and a small pose jitter.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..models.camera import look_at
from ..validation import check_number, in_range

Poses = tuple[np.ndarray, np.ndarray]  # (N, 3, 3) rotations, (N, 3) positions
FreeSpace = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (origin, unit dirs (k, 3)) -> distances (k,)

CLEARANCE = 0.3   # m the camera keeps from any surface when the rig can see the scene's geometry


@dataclass(frozen=True)
class Rig:
    """Where trajectories are placed in a scene."""

    center: np.ndarray        # anchor point of every trajectory
    view: np.ndarray | None   # fixed viewing direction for a wall, None for an enclosure
    axis: np.ndarray          # long horizontal axis of the landmark cloud
    half_extent: float        # half length of the landmark cloud along ``axis``
    half_width: float         # half extent across ``axis`` (horizontal)
    motion: float             # default size of a trajectory (circle radius etc.), m


def rig_for(landmarks: np.ndarray, normals: np.ndarray, fovy: float, aspect: float,
            free: FreeSpace | None = None) -> Rig:
    """The rig from landmark positions and outward normals (L, 3); ``free``
    (``Scene.free_distance``) keeps it clear of surfaces: a wall is viewed from no farther than the
    space in front allows, an enclosure's anchor moved off pillars and kept between floor and
    ceiling."""
    centroid = landmarks.mean(axis=0)
    flat = landmarks[:, :2] - centroid[:2]
    _, _, vt = np.linalg.svd(flat, full_matrices=False)
    axis = np.array([vt[0, 0], vt[0, 1], 0.0])
    axis *= np.sign(axis[np.argmax(np.abs(axis))])
    across = np.array([-axis[1], axis[0], 0.0])
    half_extent = float(np.abs(flat @ axis[:2]).max())
    half_width = float(np.abs(flat @ across[:2]).max())
    mean_normal = normals.mean(axis=0)
    if np.linalg.norm(mean_normal) > 0.5:
        n = mean_normal / np.linalg.norm(mean_normal)
        spread = max(np.ptp(landmarks @ axis), np.ptp(landmarks[:, 2]), 0.5)
        tan_h = np.tan(np.deg2rad(fovy) / 2) * aspect
        distance = max(0.7 * spread / (2 * tan_h), 0.8)
        if free is not None:  # not through the wall opposite; from 5 cm out, clear of the wall itself
            room = 0.05 + float(free(centroid + 0.05 * n, n[None])[0])
            distance = min(distance, max(room - CLEARANCE, 0.3))
        return Rig(centroid + n * distance, -n, axis, half_extent, half_width, 0.15 * spread)
    motion = min(1.0, 0.3 * half_width)
    center = centroid
    if free is not None:
        center, clearance = open_anchor(centroid, landmarks, normals, free, motion + CLEARANCE)
        motion = min(motion, max(clearance - CLEARANCE, 0.0))
    return Rig(center, None, axis, half_extent, half_width, motion)


def _horizontal_dirs(k: int = 24) -> np.ndarray:
    ang = 2 * np.pi * np.arange(k) / k
    return np.column_stack([np.cos(ang), np.sin(ang), np.zeros(k)])


def _clearance(free: FreeSpace, point: np.ndarray) -> float:
    """Smallest horizontal free distance around ``point`` (0 inside a solid)."""
    return float(free(point, _horizontal_dirs()).min())


def _height_between_floor_and_ceiling(free: FreeSpace, point: np.ndarray) -> np.ndarray:
    """``point`` kept ``CLEARANCE`` above the floor and below the ceiling (an open top is no limit)."""
    down, up = free(point, np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]))
    if not (np.isfinite(down) and down > 0):
        return point
    lo, hi = point[2] - down + CLEARANCE, point[2] + up - CLEARANCE
    z = (lo + hi) / 2 if lo > hi else float(np.clip(point[2], lo, hi))
    return np.array([point[0], point[1], z])


def open_anchor(centroid: np.ndarray, landmarks: np.ndarray, normals: np.ndarray, free: FreeSpace, need: float,
                grid: int = 15) -> tuple[np.ndarray, float]:
    """The enclosure's anchor and its clearance: the landmark centroid when it has ``need`` metres
    free around it; else the grid point over the landmarks' footprint, in front of as many landmarks
    as the centroid (inside the enclosure), with the most clearance, nearest the centroid among
    equals."""
    def in_front(point: np.ndarray) -> int:
        return int(np.sum(np.einsum("ij,ij->i", normals, point - landmarks) > 0))

    center = _height_between_floor_and_ceiling(free, centroid)
    clearance = _clearance(free, center)
    if clearance >= need:
        return center, clearance
    lo, hi = landmarks[:, :2].min(axis=0), landmarks[:, :2].max(axis=0)
    inside = in_front(center)
    best, best_score = center, (round(min(clearance, 2 * need), 2), 0.0)
    for x in np.linspace(lo[0], hi[0], grid):
        for y in np.linspace(lo[1], hi[1], grid):
            point = _height_between_floor_and_ceiling(free, np.array([x, y, centroid[2]]))
            if in_front(point) < inside:
                continue
            # clearance beyond twice the need buys nothing: then prefer the point nearest the centroid
            score = (round(min(_clearance(free, point), 2 * need), 2), -float(np.linalg.norm(point[:2] - centroid[:2])))
            if score > best_score:
                best, best_score = point, score
    return best, _clearance(free, best)


def _frame_poses(pos: np.ndarray, forward: np.ndarray) -> Poses:
    rots = np.stack([look_at(p, p + f) for p, f in zip(pos, forward)])
    return rots, pos


def _plane(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane a circle or figure-eight is drawn in."""
    if rig.view is None:
        return rig.axis, np.array([-rig.axis[1], rig.axis[0], 0.0])
    return rig.axis, np.array([0.0, 0.0, 1.0])


def _heading(rig: Rig, pos: np.ndarray, radial: np.ndarray | None = None) -> np.ndarray:
    if rig.view is not None:
        return np.repeat(rig.view[None], len(pos), axis=0)
    if radial is not None:
        return radial
    tangent = np.gradient(pos, axis=0)
    tangent[:, 2] = 0.0
    return tangent / np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)


def circle(rig: Rig, t: np.ndarray, radius: float | None = None, turns: float = 1.0) -> Poses:
    """Circle of ``radius`` around the rig centre; an enclosure is viewed looking outward."""
    e1, e2 = _plane(rig)
    radius = rig.motion if radius is None else radius
    ang = 2 * np.pi * turns * t
    radial = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
    pos = rig.center + radius * radial
    return _frame_poses(pos, _heading(rig, pos, radial if rig.view is None else None))


def line(rig: Rig, t: np.ndarray, length: float | None = None) -> Poses:
    """Straight line along the long axis, looking forward in an enclosure (corridor)."""
    if length is None:
        length = 1.2 * rig.half_extent if rig.view is None else 0.5 * rig.half_extent
    start = rig.center - rig.axis * (length / 2 if rig.view is not None else rig.half_extent * 0.9)
    pos = start + np.outer(t, rig.axis * length)
    forward = np.repeat(rig.axis[None], len(t), axis=0) if rig.view is None else _heading(rig, pos)
    return _frame_poses(pos, forward)


def figure_eight(rig: Rig, t: np.ndarray, radius: float | None = None) -> Poses:
    """Lemniscate of Gerono with lobes ``radius`` wide; heading follows the path indoors."""
    e1, e2 = _plane(rig)
    radius = rig.motion if radius is None else radius
    ang = 2 * np.pi * t
    pos = rig.center + radius * (np.sin(ang)[:, None] * e1 + (np.sin(ang) * np.cos(ang))[:, None] * e2)
    return _frame_poses(pos, _heading(rig, pos))


def loop(rig: Rig, t: np.ndarray, radius: float | None = None, revisit: float = 0.25) -> Poses:
    """Rounded square loop driven ``1 + revisit`` times round, so its start is seen again."""
    e1, e2 = _plane(rig)
    radius = rig.motion if radius is None else radius
    ang = 2 * np.pi * (1 + revisit) * t
    c, s = np.cos(ang), np.sin(ang)
    # superellipse |x|^4 + |y|^4 = 1: a square with rounded corners
    x = np.sign(c) * np.abs(c) ** 0.5
    y = np.sign(s) * np.abs(s) ** 0.5
    pos = rig.center + radius * (x[:, None] * e1 + y[:, None] * e2)
    return _frame_poses(pos, _heading(rig, pos))


@dataclass(frozen=True)
class Keyframes:
    """Poses a user path goes through: camera-to-world rotations (K, 3, 3) in OpenCV axes,
    positions (K, 3) and times (K,) rising from 0 to 1 (the share of the sequence)."""

    rotations: np.ndarray
    positions: np.ndarray
    times: np.ndarray


def through_keyframes(keys: Keyframes, t: np.ndarray) -> Poses:
    """Poses at times ``t`` in [0, 1]: positions linear between keyframes, orientations by slerp."""
    from scipy.spatial.transform import Rotation, Slerp

    pos = np.column_stack([np.interp(t, keys.times, keys.positions[:, i]) for i in range(3)])
    if len(keys.times) == 1:
        return np.repeat(keys.rotations[:1], len(t), axis=0), pos
    rots = Slerp(keys.times, Rotation.from_matrix(keys.rotations))(np.clip(t, 0.0, 1.0)).as_matrix()
    return rots, pos


def waypoints(rig: Rig, t: np.ndarray, keys: Keyframes) -> Poses:
    """Through the waypoints of a CSV or YAML file (``trajectory_params: {file: path}``)."""
    return through_keyframes(keys, t)


def mjcf_cameras(rig: Rig, t: np.ndarray, keys: Keyframes) -> Poses:
    """Through the MJCF's own cameras in order (``trajectory_params: {cameras: [names]}``)."""
    return through_keyframes(keys, t)


TRAJECTORIES: dict[str, Callable[..., Poses]] = {
    "circle": circle, "line": line, "figure-eight": figure_eight, "loop": loop,
    "waypoints": waypoints, "mjcf-cameras": mjcf_cameras,
}
KEYFRAMED = ("waypoints", "mjcf-cameras")   # paths the user gives; they need ``Keyframes``
OPEN_PATHS = ("line",) + KEYFRAMED            # run from start to end (no seeded start phase)


USER_PATH_KEYS = {"waypoints": {"file"}, "mjcf-cameras": {"cameras"}}   # read by ``waypoints.user_keyframes``
# ranges of the numeric trajectory parameters (m, turns, degrees): a negative radius or zero length
# would silently draw another path
PARAM_RANGES = {"radius": in_range(0, 100, lo_open=True), "length": in_range(0, 1000, lo_open=True),
                "turns": in_range(0, 100, lo_open=True), "revisit": in_range(0, 10),
                "jitter_pos": in_range(0, 1), "jitter_deg": in_range(0, 45)}


def check_trajectory_params(name: str, params: dict) -> None:
    """Refuse a parameter trajectory ``name`` does not take or a number outside ``PARAM_RANGES``
    (one line naming ``trajectory_params.<key>``)."""
    accepted = set(inspect.signature(TRAJECTORIES[name]).parameters) - {"rig", "t", "keys"}
    accepted |= {"jitter_pos", "jitter_deg"} | USER_PATH_KEYS.get(name, set())
    for key, value in params.items():
        if key not in accepted:
            raise UserError(f"trajectory {name!r} takes no parameter {key!r}; it takes "
                            f"{', '.join(sorted(accepted))}")
        if key in PARAM_RANGES:
            lo, hi, lo_open, hi_open = PARAM_RANGES[key]["range"]
            check_number(value, f"trajectory_params.{key}", lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open)


def make_trajectory(name: str, rig: Rig, frames: int, seed: int = 0, jitter_pos: float = 0.01,
                    jitter_deg: float = 0.5, keys: Keyframes | None = None, **params) -> Poses:
    """Camera poses ``(R, p)`` of ``frames`` frames of trajectory ``name``: ``seed`` draws the start
    phase of closed paths and a Gaussian jitter (``jitter_pos`` m, ``jitter_deg``); open paths
    (``line``, and ``waypoints``, ``mjcf-cameras`` through ``keys``) run start to end.
    """
    if name not in TRAJECTORIES:
        raise UserError(f"unknown trajectory {name!r}: choose one of {', '.join(TRAJECTORIES)}")
    if int(frames) < 1:
        raise UserError(f"frames must be a positive integer, got {frames!r}")
    check_trajectory_params(name, {"jitter_pos": jitter_pos, "jitter_deg": jitter_deg, **params})
    if name in KEYFRAMED:
        if keys is None:
            raise UserError(f"trajectory {name!r} needs its keyframes (the file or the MJCF cameras)")
        params = {"keys": keys, **params}
    rng = np.random.default_rng([int(seed), 7])
    if name in OPEN_PATHS:
        t = np.linspace(0.0, 1.0, frames)
    else:  # closed paths start at a seeded phase
        t = np.arange(frames) / frames + rng.uniform()
    try:
        rots, pos = TRAJECTORIES[name](rig, t, **params)
    except TypeError as exc:
        raise UserError(f"bad parameter for trajectory {name!r}: {exc}") from None
    pos = pos + rng.normal(0.0, jitter_pos, pos.shape)
    angles = np.deg2rad(rng.normal(0.0, jitter_deg, (frames, 3)))
    rots = np.stack([r @ _small_rotation(a) for r, a in zip(rots, angles)])
    return rots, pos


def _small_rotation(a: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(a).as_matrix()
