"""A synthetic lines world for the lines track's estimator tests (no MuJoCo): an 8 × 6 m room
centred on the origin with a 0.8 × 0.6 m pillar, a robot on an elliptic loop around the pillar,
and per-frame "extracted" lines = the true prediction of each visible map line plus noise drawn
from the R the extractor reports. Its ``LineSeq`` has the fields of ``tracks.lines.sequence.LineSequence``
that the belief, the estimator registry and the loop sensor read.

Map lines (α_w, r_w), r_w ≥ 0 about the world origin (the room is centred on it, so no line
passes through the origin):

    0: wall x = 4   (0, 4)        1: wall x = −4  (−π, 4)     2: wall y = 3  (π/2, 3)
    3: wall y = −3  (−π/2, 3)     4: pillar x = 0.7 (0, 0.7)  5: pillar x = −0.1 (−π, 0.1)
    6: pillar y = 0.5 (π/2, 0.5)  7: pillar y = −0.1 (−π/2, 0.1)

Walls 0 and 4 (and 1 and 5, …) are parallel look-alikes: the same α_w, r_w apart by metres.
A line is visible from a pose when one of its faces faces it and has a point within ``max_range``
(the pillar's shadow on the walls is not modelled: every line stays extractable somewhere).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from assocbench.estimators.base import FrameData, Motion
from assocbench.models.polar_line import line_from_points, predict
from assocbench.models.range_bearing import wrap
from assocbench.models.se2 import between, rot2
from assocbench.sim.robot_path import PosesInPlane

ROOM = (4.0, 3.0)                    # half sizes: the room is [−4, 4] × [−3, 3]
PILLAR = ((-0.1, -0.1), (0.7, 0.5))  # lower-left and upper-right corners
SIGMA_ALPHA_DEG, SIGMA_R = 0.5, 0.01
SIGMA_T, SIGMA_H_DEG = 0.01, 0.3


def room_map() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(lines (8, 2), segments (8, 2, 2), segment_line (8,), segment_normal (8, 2))``: the room's
    four inner faces (normals into the room) and the pillar's four faces (normals out of it)."""
    X, Y = ROOM
    (a, b), (c, d) = PILLAR
    faces = [((X, -Y), (X, Y), (-1, 0)), ((-X, -Y), (-X, Y), (1, 0)), ((-X, Y), (X, Y), (0, -1)),
             ((-X, -Y), (X, -Y), (0, 1)), ((c, b), (c, d), (1, 0)), ((a, b), (a, d), (-1, 0)),
             ((a, d), (c, d), (0, 1)), ((a, b), (c, b), (0, -1))]
    segments = np.array([[p, q] for p, q, _ in faces], dtype=float)
    normals = np.array([n for _, _, n in faces], dtype=float)
    lines = np.array([line_from_points(p, q) for p, q in segments])
    return lines, segments, np.arange(len(faces)), normals


def visible_lines(pose: np.ndarray, segments: np.ndarray, segment_line: np.ndarray, normals: np.ndarray,
                  n_lines: int, max_range: float) -> np.ndarray:
    """(K,) the lines the synthetic extractor reports at the true ``pose`` (module docstring)."""
    rel = segments[:, 0] - pose[:2]
    d = segments[:, 1] - segments[:, 0]
    t = np.clip(-np.einsum("sk,sk->s", rel, d) / np.einsum("sk,sk->s", d, d), 0.0, 1.0)
    near = np.linalg.norm(rel + t[:, None] * d, axis=1) <= max_range
    faces = np.einsum("sk,sk->s", -rel, normals) > 0
    out = np.zeros(n_lines, dtype=bool)
    out[segment_line[near & faces]] = True
    return out


@dataclass
class LineSeq(PosesInPlane):
    """The fields of a ``LineSequence`` (``tracks.lines.sequence``) the lines track's belief reads, plus
    ``motions`` (odometry from k − 1 to k, ``motions[0]`` unused) for tests that drive a filter."""

    poses: np.ndarray
    lines: np.ndarray
    segments: np.ndarray
    segment_line: np.ndarray
    segment_normal: np.ndarray
    z: list[np.ndarray]
    R: list[np.ndarray]
    labels: list[np.ndarray]
    endpoints: list[np.ndarray]
    visible: np.ndarray
    max_range: float
    fov: float
    nominal_R: np.ndarray
    motions: list[Motion] = field(default_factory=list)
    final_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))   # no scan: the top view draws segments only
    track: str = "lines"

    @property
    def landmarks(self) -> np.ndarray:
        return self.lines

    def frame(self, k: int) -> FrameData:
        return FrameData(self.z[k], self.R[k])


def loop_poses(steps: int, laps: float = 1.0, a: float = 2.8, b: float = 1.9) -> np.ndarray:
    """``steps`` poses on the ellipse with semi-axes ``a`` × ``b`` about the origin (round the
    pillar), heading along it (counter-clockwise)."""
    t = np.linspace(0, 2 * np.pi * laps, steps, endpoint=False)
    return np.column_stack([a * np.cos(t), b * np.sin(t), wrap(np.arctan2(b * np.cos(t), -a * np.sin(t)))])


def measure(pose: np.ndarray, lines: np.ndarray, seen: np.ndarray, R: np.ndarray,
            rng: np.random.Generator) -> np.ndarray:
    """The extracted lines ``h(pose, m_j) + n``, ``n ~ N(0, R)``, α wrapped, r ≥ 0 kept."""
    z = predict(pose, lines[seen]) + rng.multivariate_normal(np.zeros(2), R, len(seen))
    z[:, 0] = wrap(z[:, 0])
    return z


def line_seq(steps: int = 200, seed: int = 0, max_range: float = 6.0, fov: float = 2 * np.pi,
             poses: np.ndarray | None = None) -> LineSeq:
    """The room seen along ``poses`` (default: one lap of ``loop_poses(steps)``) with
    ``R = diag(σ_α², σ_r²)`` (0.5°, 1 cm) per extracted line and planar odometry with
    ``Q = diag(σ_t², σ_t², σ_h²)`` (1 cm, 0.3°) per step, all drawn from ``seed``."""
    rng = np.random.default_rng([seed, 303])
    poses = loop_poses(steps) if poses is None else np.asarray(poses, dtype=float).reshape(-1, 3)
    lines, segments, seg_line, normals = room_map()
    R = np.diag([np.deg2rad(SIGMA_ALPHA_DEG) ** 2, SIGMA_R ** 2])
    Q = np.diag([SIGMA_T ** 2, SIGMA_T ** 2, np.deg2rad(SIGMA_H_DEG) ** 2])
    z, Rs, labels, ends, vis, motions = [], [], [], [], [], [Motion(np.zeros(3), Q)]
    for k, pose in enumerate(poses):
        v = visible_lines(pose, segments, seg_line, normals, len(lines), max_range)
        seen = np.flatnonzero(v)
        z.append(measure(pose, lines, seen, R, rng))
        Rs.append(np.repeat(R[None], len(seen), axis=0))
        labels.append(seen.astype(np.int64))
        ends.append(np.einsum("ij,snj->sni", rot2(pose[2]).T, segments[seen] - pose[:2]))   # robot frame
        vis.append(v)
        if k:
            motions.append(Motion(between(poses[k - 1], pose) + rng.multivariate_normal(np.zeros(3), Q), Q))
    return LineSeq(poses, lines, segments, seg_line, normals, z, Rs, labels, ends, np.array(vis), max_range, fov,
                   R, motions)
