"""One 2-D lidar scan: what ``lidar.scan`` returns and the scenes' truth (``line_scene.beam_lines``) reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cache import storable


@storable
@dataclass
class Scan:
    """One scan; ``geom`` and ``distance`` are the truth, the geom each ray meets first within
    ``max_range`` (−1) and how far (``inf``), kept where the return dropped out (``distance`` None
    for scans made without it)."""

    angles: np.ndarray   # (B,) robot frame (rad)
    ranges: np.ndarray   # (B,) measured (m), NaN: no return
    geom: np.ndarray     # (B,) int, hit geom id or -1
    full_circle: bool = True   # the beams cover 360° (beam B−1 neighbours beam 0)
    distance: np.ndarray | None = None   # (B,) true distance d_i (m), inf: no hit within max_range

    def points(self) -> np.ndarray:
        """Hit points (B, 2) in the robot frame, ``r_i (cos α_i, sin α_i)`` (NaN without return)."""
        return self.ranges[:, None] * np.column_stack([np.cos(self.angles), np.sin(self.angles)])
