"""The recorded track's closed loop: the log's own odometry and sightings drive the planar EKF-SLAM or
iSAM2 back end, and each frame records which landmark the run put each sighting on (for the
pairwise "same landmark" scores, ``scoring.pairwise``)."""

from __future__ import annotations

import json
from functools import cache

import numpy as np

from ...estimators.base import FrameData, Motion
from ...models.se2 import compose
from ...scoring.pairwise import same_landmark_scores
from ..plane_sensor import PlanarSensor

REFS, ENTRIES = "sighting_refs", "sighting_entries"   # per-frame columns: JSON lists, one item a feature


class DecisionLog:
    """Mixed into a planar back end: ``entries`` (m,) the map id each feature of the frame was
    paired with or made into (−1: none), after update and initialisation."""

    entries: np.ndarray

    def problem(self, frame: FrameData):
        problem = super().problem(frame)
        self.entries = np.full(len(frame.z), -1, np.int64)
        self._candidate_ids = problem.landmark_ids
        return problem

    def update(self, association: np.ndarray):
        report = super().update(association)
        a = np.asarray(association, np.int64)
        self.entries[a[a >= 0]] = self._candidate_ids[a >= 0]
        return report

    def initialise(self, frame: FrameData, features: np.ndarray):
        made = super().initialise(frame, features)
        for map_id, feature in made:
            self.entries[feature] = map_id
        return made


@cache
def logged(cls: type) -> type:
    """``cls`` (a planar back end) with the ``DecisionLog`` mixed in."""
    return type(f"Logged{cls.__name__}", (DecisionLog, cls), {})


class LogSensor(PlanarSensor):
    """``PlanarSensor`` on a recorded log: the log's odometry composed between frames (covariance
    times ``log.odometry_scale``), sightings with their own noise, pose errors against the reference
    solution."""

    def motion(self, k: int) -> Motion:
        motion = Motion(self.seq.increments[k], self.seq.motion_covariances[k])
        self.dead_reckoning = compose(self.dead_reckoning, motion.increment)
        return motion

    def state_columns(self, f, k: int) -> dict:
        """The planar columns, and each feature's reference landmark and the map entry it went to."""
        refs = np.concatenate([self.seq.labels[k], np.full(self.belief.clutter, -1)]).astype(int)
        return super().state_columns(f, k) | {REFS: json.dumps(refs.tolist()),
                                              ENTRIES: json.dumps(np.asarray(f.entries).tolist())}


def run_scores(frames) -> dict:
    """``pair_precision`` and ``pair_recall`` of the run's sightings (``scoring.pairwise``, by map
    id) and ``reference_landmarks`` its frames sighted; NaN where no frame recorded them."""
    rows = frames[[REFS, ENTRIES]].dropna() if REFS in frames and ENTRIES in frames else frames.iloc[:0]
    refs = [np.array(json.loads(r), np.int64) for r in rows[REFS]]
    entries = [np.array(json.loads(e), np.int64) for e in rows[ENTRIES]]
    if not refs:
        return {"pair_precision": float("nan"), "pair_recall": float("nan"), "reference_landmarks": float("nan")}
    r, e = np.concatenate(refs), np.concatenate(entries)
    return same_landmark_scores(e, r) | {"reference_landmarks": int(len(np.unique(r[r >= 0])))}
