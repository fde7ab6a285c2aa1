"""A synthetic 2-D world of wall faces for the line extractor's tests (no MuJoCo): faces are
segments with a map-line id, beams are ray-cast analytically, ranges get N(0, σ²) noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assocbench.models.range_bearing import wrap
from assocbench.sim.scan import Scan
from assocbench.sim.settings import LidarConfig


@dataclass
class World:
    faces: np.ndarray      # (F, 2, 2) segment end points
    face_line: np.ndarray  # (F,) map line of each face
    lines: np.ndarray      # (K, 2) world (α_w, r_w), r_w >= 0


def _line(p: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """(α, r) of the infinite line through p and q, r >= 0."""
    d = q - p
    n = np.array([d[1], -d[0]]) / np.hypot(*d)
    r = float(n @ p)
    return (float(wrap(np.arctan2(n[1], n[0]) + (np.pi if r < 0 else 0))), abs(r))


def box_faces(cx: float, cy: float, w: float, h: float) -> list[np.ndarray]:
    """The 4 faces (2, 2) of an axis-aligned box centred at (cx, cy)."""
    c = np.array([[cx - w / 2, cy - h / 2], [cx + w / 2, cy - h / 2], [cx + w / 2, cy + h / 2], [cx - w / 2, cy + h / 2]])
    return [np.array([c[k], c[(k + 1) % 4]]) for k in range(4)]


def world(faces: list[np.ndarray]) -> World:
    """A world whose faces each lie on their own map line (none collinear here)."""
    f = np.array(faces, float)
    lines = np.array([_line(a, b) for a, b in f])
    return World(f, np.arange(len(f)), lines)


def room(pillar: bool = True, corner_gap: float = 0.0) -> World:
    """A 6 x 4 m room ([0, 6] x [0, 4]) with a 0.6 m square pillar at (4.2, 2.6); ``corner_gap``
    shortens each wall at both ends (open corners: beams escape there)."""
    walls = box_faces(3.0, 2.0, 6.0, 4.0)
    if corner_gap:
        unit = [(f[1] - f[0]) / np.hypot(*(f[1] - f[0])) for f in walls]
        walls = [np.array([f[0] + corner_gap * u, f[1] - corner_gap * u]) for f, u in zip(walls, unit)]
    return world(walls + (box_faces(4.2, 2.6, 0.6, 0.6) if pillar else []))


def cast(w: World, pose: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """True distance (B,) (inf: nothing within max_range) and face hit (B,) (−1) of rays from pose."""
    o = np.asarray(pose[:2], float)
    u = np.column_stack([np.cos(angles + pose[2]), np.sin(angles + pose[2])])      # (B, 2)
    a, e = w.faces[:, 0], w.faces[:, 1] - w.faces[:, 0]                           # (F, 2)
    den = u[:, None, 0] * e[None, :, 1] - u[:, None, 1] * e[None, :, 0]            # cross(u, e)
    ao = a[None] - o
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ao[..., 0] * e[None, :, 1] - ao[..., 1] * e[None, :, 0]) / den       # along the ray
        s = (ao[..., 0] * u[:, None, 1] - ao[..., 1] * u[:, None, 0]) / den       # along the face
    t = np.where((np.abs(den) > 1e-12) & (t > 0) & (s >= 0) & (s <= 1), t, np.inf)
    face = np.argmin(t, axis=1)
    dist = t[np.arange(len(u)), face]
    hit = dist <= max_range
    return np.where(hit, dist, np.inf), np.where(hit, face, -1)


def synth_scan(w: World, pose: np.ndarray, sigma: float = 0.01, beams: int = 360, fov_deg: float = 360.0,
               max_range: float = 10.0, seed: int = 0) -> tuple[Scan, np.ndarray]:
    """A scan from ``pose`` and each beam's true map line (−1: no return)."""
    cfg = LidarConfig(beams=beams, fov_deg=fov_deg, max_range=max_range, sigma_range=sigma)
    angles = cfg.angles()
    dist, face = cast(w, pose, angles, max_range)
    ranges = dist + sigma * np.random.default_rng([seed, 7]).standard_normal(len(angles))
    ranges[~(ranges <= max_range)] = np.nan
    return Scan(angles, ranges, face, cfg.full_circle), np.where(face >= 0, w.face_line[np.maximum(face, 0)], -1)


def robot_lines(w: World, pose: np.ndarray) -> np.ndarray:
    """Map lines (K, 2) in the robot frame: ``[α_w − θ, r_w − (x cos α_w + y sin α_w)]``, r >= 0."""
    a, r = w.lines[:, 0], w.lines[:, 1]
    z = np.column_stack([a - pose[2], r - (pose[0] * np.cos(a) + pose[1] * np.sin(a))])
    neg = z[:, 1] < 0
    z[neg] = z[neg] * [1, -1] + [np.pi, 0]
    z[:, 0] = wrap(z[:, 0])
    return z
