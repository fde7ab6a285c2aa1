"""Named, parameterised, seeded camera trajectories.

Each trajectory is placed and sized (``radius`` defaults to the rig's ``motion``) by a *rig*
derived from the scene's landmarks alone, so a user MJCF works without configuration: a scene whose landmark normals agree (a wall) is viewed
from in front along the mean normal; an enclosure (room, corridor) is viewed from inside its
landmark centroid, along its long axis when it is elongated. Parameters are in metres and
degrees; ``seed`` sets the start phase and a small per-frame pose jitter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import UserError
from .camera import look_at

Poses = tuple[np.ndarray, np.ndarray]  # (N, 3, 3) rotations, (N, 3) positions


@dataclass(frozen=True)
class Rig:
    """Where trajectories are placed in a scene."""

    center: np.ndarray        # anchor point of every trajectory
    view: np.ndarray | None   # fixed viewing direction for a wall, None for an enclosure
    axis: np.ndarray          # long horizontal axis of the landmark cloud
    half_extent: float        # half length of the landmark cloud along ``axis``
    half_width: float         # half extent across ``axis`` (horizontal)
    motion: float             # default size of a trajectory (circle radius etc.), m


def rig_for(landmarks: np.ndarray, normals: np.ndarray, fovy: float, aspect: float) -> Rig:
    """Derive the rig from landmark positions (L, 3) and outward normals (L, 3)."""
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
        return Rig(centroid + n * distance, -n, axis, half_extent, half_width, 0.15 * spread)
    return Rig(centroid, None, axis, half_extent, half_width, min(1.0, 0.3 * half_width))


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


TRAJECTORIES: dict[str, Callable[..., Poses]] = {
    "circle": circle, "line": line, "figure-eight": figure_eight, "loop": loop,
}


def make_trajectory(name: str, rig: Rig, frames: int, seed: int = 0,
                    jitter_pos: float = 0.01, jitter_deg: float = 0.5, **params) -> Poses:
    """Camera poses ``(R, p)`` of ``frames`` frames of trajectory ``name``.

    ``seed`` draws the start phase of closed paths and a small Gaussian jitter of the
    position (``jitter_pos`` m) and orientation (``jitter_deg``) of every frame.
    """
    if name not in TRAJECTORIES:
        raise UserError(f"unknown trajectory {name!r}: choose one of {', '.join(TRAJECTORIES)}")
    if int(frames) < 1:
        raise UserError(f"frames must be a positive integer, got {frames!r}")
    rng = np.random.default_rng([int(seed), 7])
    if name == "line":
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
