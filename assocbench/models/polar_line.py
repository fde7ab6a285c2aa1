"""An infinite line in polar form, measured from a planar robot (the line-features lecture, seed
003).

A line is ``{p : p·(cos α, sin α) = r}`` with **r ≥ 0**, α wrapped to [−π, π) (at r = 0 the given
name of α, α + π is kept). A map line ``(α_w, r_w)`` seen from ``(x, y, θ)`` is predicted as

    ẑ = h(x, m) = [α_w − θ,  r_w − (x cos α_w + y sin α_w)]

and a negative r (the robot across the line from the origin) becomes ``(α_w − θ + π, −r)``, flipping
the r row of each Jacobian:

    ∂h/∂(x, y, θ) = [[0, 0, −1], [−s cos α_w, −s sin α_w, 0]],
    ∂h/∂(α_w, r_w) = [[1, 0], [s (x sin α_w − y cos α_w), s]],      s = sign of the unflipped r.

α wraps (``ANGULAR``): the association compares it modulo 2π.
"""

from __future__ import annotations

import numpy as np

from .range_bearing import wrap

ANGULAR = (0,)   # α wraps: the Problem's angular dims


def _as_lines(lines: np.ndarray) -> np.ndarray:
    return np.asarray(lines, dtype=np.float64).reshape(-1, 2)


def _unflipped(pose: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(α_w − θ, r_w − (x cos α_w + y sin α_w))`` per line, before the r ≥ 0 convention."""
    L = _as_lines(lines)
    x, y, th = np.asarray(pose, dtype=np.float64)[:3]
    return L[:, 0] - th, L[:, 1] - (x * np.cos(L[:, 0]) + y * np.sin(L[:, 0]))


def normalise(alpha: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Lines ``(n, 2)`` in the r ≥ 0 convention: ``(α, r)`` or ``(α + π, −r)``, α wrapped."""
    alpha, r = np.asarray(alpha, dtype=np.float64), np.asarray(r, dtype=np.float64)
    flip = r < 0
    return np.column_stack([wrap(np.where(flip, alpha + np.pi, alpha)), np.abs(r)])


def predict(pose: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """``h(x, m_j)`` for every map line: (n, 2) rows ``(α, r)`` in the robot frame, r ≥ 0."""
    return normalise(*_unflipped(pose, lines))


def jacobians(pose: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(∂h/∂pose (n, 2, 3), ∂h/∂line (n, 2, 2))`` at each map line (module docstring)."""
    L = _as_lines(lines)
    x, y = float(pose[0]), float(pose[1])
    _, r = _unflipped(pose, L)
    s = np.where(r < 0, -1.0, 1.0)
    c, sn = np.cos(L[:, 0]), np.sin(L[:, 0])
    H_pose = np.zeros((len(L), 2, 3))
    H_pose[:, 0, 2] = -1.0
    H_pose[:, 1, 0], H_pose[:, 1, 1] = -s * c, -s * sn
    H_line = np.zeros((len(L), 2, 2))
    H_line[:, 0, 0] = 1.0
    H_line[:, 1, 0], H_line[:, 1, 1] = s * (x * sn - y * c), s
    return H_pose, H_line


def to_world(pose: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The world lines (n, 2) of robot-frame lines ``z = (α, r)``: the inverse of ``predict``,
    ``α_w = α + θ``, ``r_w = r + x cos α_w + y sin α_w`` (then r_w ≥ 0)."""
    Z = _as_lines(z)
    x, y, th = np.asarray(pose, dtype=np.float64)[:3]
    aw = Z[:, 0] + th
    return normalise(aw, Z[:, 1] + x * np.cos(aw) + y * np.sin(aw))


def line_from_points(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``(α, r)`` of the line through ``p`` and ``q``: normal ``n = (−d_y, d_x) / ‖d‖``,
    ``d = q − p``, ``r = p·n``, then r ≥ 0; equal points: ``ValueError``."""
    p, q = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
    d = q - p
    length = float(np.hypot(*d))
    if length <= 0:
        raise ValueError("a line needs two distinct points")
    n = np.array([-d[1], d[0]]) / length
    return normalise(np.arctan2(n[1], n[0]), float(p @ n))[0]
