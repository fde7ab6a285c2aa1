"""What the lines track's closed loop reads: the planar sensor with extracted wall lines for posts."""

from __future__ import annotations

import numpy as np

from ..plane_sensor import PlanarSensor
from .belief import clutter_lines
from .plots import segment_status, snapshot_json


class LinesSensor(PlanarSensor):
    """The lines track's loop sensor: extracted lines (the extractor's covariance) plus uniform
    clutter lines, planar odometry, 3-dof pose error. Localisation only: no new-landmark gate."""

    new_landmark_gate = 0.0   # unused: the lines track makes no landmarks
    clutter = staticmethod(clutter_lines)

    def snapshot(self, k: int, pose: np.ndarray, problem, association: np.ndarray, labels: np.ndarray) -> str:
        """The last frame for the top view: scan points, extracted segments and what the method did
        with each, drawn at the estimated ``pose``."""
        m = len(self.seq.z[k])   # the extracted lines; the clutter lines after them have no segment
        status = segment_status(labels, problem.landmark_ids, association, m)
        return snapshot_json(pose, self.seq.final_points, self.seq.endpoints[k], status)
