"""The closed loop (``--loop``): the belief of frame k is the estimator's posterior after frames < k
were updated with the method's own pairings.

Per frame: predict with odometry (k > 0), build the problem from the estimator, call the method
(``oracle``: the true association), update with its answer, and in slam mode make landmarks of the
unassociated features. A failed frame (raised, timed out, invalid answer) updates nothing.
``replay`` gives the associations of recorded frames, so a resumed worker rebuilds the same filter
without calling the method. An estimator that raises (GTSAM's iSAM2) ends its own run only: that
frame and the rest fail with ``EstimatorFailed at frame k: ...``, the run is not ok, and a job's
other runs keep their results.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from ..association.compatibility import pairwise_nis
from ..association.problem import NO_MATCH, Problem
from ..association.truth import FrameTruth
from ..errors import UserError
from ..estimators.ekf_core import NotPositiveDefinite
from ..scoring.loop_summary import ESTIMATOR_FAILED
from ..scoring.metrics import score_frame, true_mass
from ..tracks.registry import get_track
from .config import ORACLE
from .loop_truth import MapTruth, RevisitCounter, loop_truth, map_quality
from .runner import WARM_UP, _build, call_method, checked_truth, describe, failed_record, warm_up


class EstimatorFailed(RuntimeError):
    """The estimator raised while the closed loop used it: its run cannot go on (module docstring)."""


def _guarded(fn: Callable, *args, **kwargs):
    """``fn(*args, **kwargs)`` with its exceptions made ``EstimatorFailed``, except ``UserError``
    and a not-positive-definite update (a failed frame)."""
    try:
        return fn(*args, **kwargs)
    except (UserError, NotPositiveDefinite):
        raise
    except Exception as exc:  # noqa: BLE001 - a back end's own exception (GTSAM's RuntimeError, ...)
        raise EstimatorFailed(describe(exc)) from exc


class GuardedEstimator:
    """The estimator as the loop uses it: every call and property through ``_guarded``, so a back
    end's failure is told from the harness's."""

    def __init__(self, inner) -> None:
        object.__setattr__(self, "_inner", inner)

    def __getattr__(self, name: str):
        inner = self._inner
        if not hasattr(type(inner), name) and name not in getattr(inner, "__dict__", {}):
            raise AttributeError(name)   # absent (``hasattr(f, "trajectory")`` on a filter)
        value = _guarded(getattr, inner, name)   # a property computes here
        return (lambda *a, **k: _guarded(value, *a, **k)) if callable(value) else value


class ClosedLoop:
    """One method's closed-loop run on one sequence (see the module docstring)."""

    def __init__(self, source, run) -> None:
        track = get_track(run.track)
        self.seq, self.belief, self.est, self.seed = source.sequence, run.belief, run.estimator, run.seed
        self.filter = _guarded(track.estimator, source, run)
        self._est = GuardedEstimator(self.filter)   # what the loop itself calls
        self.sensor = track.loop_sensor(source, run)
        self.revisits = RevisitCounter()
        self.truth = MapTruth()
        self.in_map = None
        self._pending: tuple | None = None   # frame begun, not finished: (k, problem, truth, data, labels)
        self._labels: dict[int, np.ndarray] = {}   # each frame's feature labels (two-view landmarks' truth)
        if self.est.mode == "localisation":
            self.in_map = np.zeros(len(self.seq.landmarks), bool)
            self.in_map[self._est.book.ids] = True
            for mid in self._est.book.ids:
                self.truth.tie(mid, mid)

    def frame(self, k: int, decide: Callable) -> dict:
        """Run frame ``k``: ``decide(problem, truth) -> (association | None, runtime, info, error)``."""
        problem, truth = self.begin(k)
        return self.finish(*decide(problem, truth))

    def begin(self, k: int) -> tuple[Problem, FrameTruth]:
        """First half of frame ``k``: predict (k > 0), then the frame's problem and truth;
        ``finish`` applies an answer; frames go in order."""
        if k > 0:
            self._est.predict(self.sensor.motion(k))
        data, labels = self.sensor.frame(k, self.in_map)
        problem = self._est.problem(data).validate()   # the whole P, before any method sees it
        ids = problem.landmark_ids
        visible = np.array([self.truth.label[i] >= 0 and self.seq.visible[k][self.truth.label[i]] for i in ids], bool)
        truth = checked_truth(self.seq.track, k, problem, loop_truth(ids, self.truth, labels, visible))
        self._pending = (k, problem, truth, data, labels)
        self._labels[k] = labels
        return problem, truth

    def finish(self, association: np.ndarray | None, runtime: float = 0.0, info: dict | None = None,
               error: str = "") -> dict:
        """Second half: update with ``association`` (None: the frame failed with ``error``) and
        return its record."""
        if self._pending is None:
            raise RuntimeError("ClosedLoop.finish without a frame begun: call begin(k) first")
        (k, problem, truth, data, labels), self._pending = self._pending, None
        born = dict(zip(self._est.book.ids, self._est.book.born))   # before this frame's new entries
        closures = self.revisits.count(k, labels, problem.landmark_ids, association, self.truth, born)
        if association is None:   # the filter only predicts through a failed frame
            record = failed_record(k, problem, truth, error, runtime)
        else:
            record = self._apply(k, problem, truth, association, data, labels, runtime, dict(info or {}))
        return record | closures | self._state_columns(k)

    def _apply(self, k, problem, truth, association, data, labels, runtime, info) -> dict:
        marginals = info.pop("marginals", None)
        record = {"frame": k, **score_frame(problem, truth, association), **info,
                  "true_mass": true_mass(marginals, truth.association) if marginals is not None else float("nan"),
                  "runtime_s": runtime, "error": "", "association": association.tolist()}
        try:
            self._est.update(association)
        except NotPositiveDefinite as exc:
            return record | {"error": f"FilterUpdate: {exc}"}
        snapshot = getattr(self.sensor, "snapshot", None)   # the last frame as the figures draw it (lines)
        if snapshot is not None and k == len(self.seq) - 1:
            record["final_scan"] = snapshot(k, self._est.pose, problem, association, labels)
        gate = self.est.new_landmark_gate
        free = new_landmark_features(problem, association, self.sensor.new_landmark_gate if gate is None else gate)
        made = self._est.initialise(data, free)
        for map_id, i in made:
            self.truth.tie(map_id, self._made_label(map_id, labels[i]))
        no_depth = int(np.sum(~np.isfinite(data.depth[free]) | (data.depth[free] <= 0))) if data.depth is not None else 0
        return record | {"new_landmarks": len(made), "no_depth": no_depth}

    def _made_label(self, map_id: int, label: int) -> int:
        """The landmark a new map entry truly is: its feature's ``label``, for a two-view one only
        if both views image it (else false)."""
        first = getattr(self._est, "first_sighting", {}).get(map_id)
        if first is None:
            return int(label)
        frame, feature = first
        return int(label) if self._labels[frame][feature] == label else NO_MATCH

    def _state_columns(self, k: int) -> dict:
        f = self._est
        quality = map_quality(f.book.ids, f.book.confirmed, f.landmarks, self.truth, self.seq.landmarks)
        out = {**self.sensor.state_columns(f, k), "tentative": int(len(f.book) - np.sum(f.book.confirmed)), **quality}
        if k == len(self.seq) - 1:   # the final map, for the figures (frames.csv records no other)
            xy = np.asarray(f.landmarks)[f.book.confirmed][:, :2] if len(f.book) else np.zeros((0, 2))
            out["final_map"] = json.dumps(np.round(xy, 4).tolist())
            if hasattr(f, "trajectory"):   # a smoother: its final estimate of every pose, not each frame's
                err = f.trajectory[:, :2] - self.seq.positions[:len(f.trajectory), :2]
                out["ate_smoothed"] = float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))
        return out


def new_landmark_features(problem: Problem, association: np.ndarray, gate: float) -> np.ndarray:
    """Unassociated features farther than ``gate`` (Mahalanobis, ``√(y_ijᵀ (P_jj + R_i)⁻¹ y_ij)``)
    from every candidate: a slam filter's new landmarks (0: all)."""
    free = np.setdiff1d(np.arange(problem.m), association[association >= 0])
    if gate <= 0 or problem.n == 0 or not len(free):
        return free.astype(np.int64)
    nis, _ = pairwise_nis(problem)
    return free[nis[free].min(axis=1) > gate ** 2].astype(np.int64)


def recorded_answer(recorded, k: int) -> tuple:
    """Frame ``k``'s recorded answer as ``decide`` returns it: the association, or a failure where
    an error or nothing was recorded."""
    association, error = recorded.get(k, (None, "not recorded"))
    if error or association is None:
        return None, 0.0, {}, error or "not recorded"
    return np.asarray(association, dtype=np.int64), 0.0, {}, ""


def loop_records(source, run, first: int = 0, faults: dict | None = None,
                 on_call: Callable[[int, float], None] = lambda k, limit: None,
                 replay: dict | None = None) -> Iterator[dict]:
    """Per-frame records of the method's closed loop on ``source`` from ``first`` (earlier frames
    replayed from ``replay``); ``faults``, ``on_call`` as ``runner.frame_records``'."""
    faults, replay = faults or {}, replay or {}
    method, params, time_limit_s = run.method, run.params, run.time_limit_s
    try:
        loop = ClosedLoop(source, run)
    except EstimatorFailed as exc:   # the estimator could not even start: no frame is measured
        yield from estimator_failed_records(range(first, len(source)), 0, exc)
        return
    seq = loop.seq
    associator, build_error = None, ""
    if method != ORACLE and WARM_UP not in faults:
        on_call(WARM_UP, 10 * time_limit_s)
        associator, build_error = _build(method, params)
        if associator is not None:
            warm_up(associator)
    start_error = faults.get(WARM_UP, (build_error, 0.0))[0] if method != ORACLE else ""

    for k in range(len(seq)):
        def decide(problem, truth, k=k):
            if k < first:
                return recorded_answer(replay, k)
            if k in faults:
                return None, faults[k][1], {}, faults[k][0]
            if method == ORACLE:
                return truth.association.copy(), 0.0, {"timed_out": False, "proven_optimal": float("nan")}, ""
            if associator is None:
                return None, 0.0, {}, start_error or "the method could not start"
            on_call(k, time_limit_s)
            return call_method(associator, problem)
        try:
            record = loop.frame(k, decide)
        except EstimatorFailed as exc:   # this run ends here; the job's other runs go on
            yield from estimator_failed_records(range(max(k, first), len(seq)), k, exc)
            return
        if k >= first:
            yield record


def estimator_failed_records(frames: Iterable[int], at: int, exc: EstimatorFailed) -> Iterator[dict]:
    """Records of ``frames`` after the estimator failed at ``at`` with ``exc``: nothing measured,
    each failed with the error."""
    nan = float("nan")
    error = f"{ESTIMATOR_FAILED} at frame {at}: {exc}"
    for k in frames:
        yield {"frame": k, "n": 0, "m": 0, "tp": 0, "fp": 0, "fn": 0, "clutter_accepted": 0, "timed_out": False,
               "proven_optimal": nan, "true_mass": nan, "runtime_s": 0.0, "error": error, "association": [],
               "nees": nan, "pos_err": nan, "rot_err_deg": nan}
