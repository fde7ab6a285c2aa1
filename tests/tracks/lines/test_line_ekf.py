"""LineEKF (EKF localisation on a known map of lines) on tests/line_synth_seq.py's room: 8 × 6 m with a
pillar, one 200-step lap of an elliptic loop, a 6 m 360° lidar whose extracted lines carry σ_α 0.5°,
σ_r 1 cm, odometry σ 1 cm, 0.3° per step; the first pose is drawn from P0 = diag(5 cm, 5 cm, 1°)².

Consistency is measured over an ensemble of seeds, as tests/test_planar_ekf.py does: the ensemble
average of NEES at one frame over M independent runs of a consistent filter is χ²_{3M}/M, whose
95 % band for M = 10 is ``anees_band(10, dof=3)`` = (1.68, 4.70).
"""

from __future__ import annotations

import numpy as np
import pytest
from line_synth_seq import line_seq
from runs import run_on

from assocbench.belief.config import BeliefConfig, true_association
from assocbench.errors import UserError
from assocbench.estimators.base import FrameData
from assocbench.estimators.config import EstimatorConfig
from assocbench.estimators.planar_ekf import PlanarEKF
from assocbench.models.polar_line import jacobians, predict
from assocbench.models.range_bearing import pose_error, wrap
from assocbench.scoring.trajectory import anees_band, ate_rmse
from assocbench.tracks.lines.belief import candidate_lines
from assocbench.tracks.lines.ekf import LineEKF
from assocbench.tracks.registry import get_track

STEPS, SEEDS = 200, 10
P0 = np.diag([0.05 ** 2, 0.05 ** 2, np.deg2rad(1.0) ** 2])


def start(seq, seed: int, **cfg) -> LineEKF:
    """The filter at a first pose drawn from P0 around the truth, every map line mapped."""
    x0 = seq.poses[0] + np.random.default_rng([seed, 7]).multivariate_normal(np.zeros(3), P0)
    return LineEKF(EstimatorConfig(**cfg), x0, P0, seq.lines, seq.segments, seq.segment_line, seq.segment_normal,
                   np.arange(len(seq.lines)), seq.max_range, seq.fov)


def nees3(e: np.ndarray, P: np.ndarray) -> float:
    w = np.linalg.solve(np.linalg.cholesky(P), e)
    return float(w @ w)


def run(ekf: LineEKF, seq, steps: int = STEPS, swap_at: int = -1) -> dict:
    """The loop with the true association; at ``swap_at`` two paired parallel lines (the same world
    α modulo π) swap their measurements. Per-frame NEES and estimated positions."""
    nees, xy = [], []
    for k in range(steps):
        if k:
            ekf.predict(seq.motions[k])
        problem = ekf.problem(seq.frame(k))
        a = true_association(seq.labels[k], problem.landmark_ids)
        if k == swap_at:
            i, j = parallel_pair(seq.lines[problem.landmark_ids], a)
            a[i], a[j] = a[j], a[i]
        ekf.update(a)
        nees.append(nees3(pose_error(seq.poses[k], ekf.pose), ekf.pose_covariance))
        xy.append(ekf.pose[:2])
    return {"nees": np.array(nees), "xy": np.array(xy)}


def parallel_pair(lines: np.ndarray, a: np.ndarray) -> tuple[int, int]:
    """Two paired candidates whose world lines are parallel (α_w equal modulo π)."""
    paired = np.flatnonzero(a >= 0)
    for n, i in enumerate(paired):
        for j in paired[n + 1:]:
            if abs(wrap(2 * (lines[i, 0] - lines[j, 0]))) < 1e-9:
                return int(i), int(j)
    raise AssertionError("no two parallel lines paired in this frame")


@pytest.fixture(scope="module")
def runs():
    out = []
    for seed in range(SEEDS):
        seq = line_seq(STEPS, seed=seed)
        out.append(run(start(seq, seed), seq) | {"ate": 0.0})
        out[-1]["ate"] = ate_rmse(seq.positions, np.column_stack([out[-1]["xy"], np.zeros(STEPS)]))
    return out


def test_true_association_is_consistent_over_an_ensemble(runs):
    """10 seeds × 200 frames: measured grand mean NEES 3.09 and 96.5 % of frames inside the per-frame
    band (1.68, 4.70); one run's ANEES has sd 0.16 around it. Asserted: grand mean within 3 ± 0.5
    and ≥ 90 % of frames in the band. ATE measured 7.5-8.5 mm per run, asserted < 2 cm."""
    nees = np.array([r["nees"] for r in runs])
    lo, hi = anees_band(SEEDS, dof=3)
    ensemble = nees.mean(axis=0)
    assert 2.5 < nees.mean() < 3.5, nees.mean()
    assert np.mean((ensemble > lo) & (ensemble < hi)) >= 0.90
    assert max(r["ate"] for r in runs) < 0.02, [r["ate"] for r in runs]


def test_swapping_two_parallel_walls_makes_nees_jump():
    """Frame 100 pairs two parallel lines (same α_w, r_w metres apart) with each other's
    measurement: NEES goes from 1.7 to 1.2e5 and the position error from 7 mm to 1.09 m (seed 0,
    measured); the true association's NEES at that frame is 1.4."""
    seq = line_seq(STEPS, seed=0)
    good = run(start(seq, 0), seq, steps=103)
    bad = run(start(seq, 0), seq, steps=103, swap_at=100)
    np.testing.assert_array_equal(good["nees"][:100], bad["nees"][:100])
    assert good["nees"][100] < 16.27   # χ²₃ 99.9 %
    assert bad["nees"][100] > 500 and bad["nees"][100] > 100 * bad["nees"][99], bad["nees"][98:101]
    err = np.linalg.norm(bad["xy"][100] - seq.poses[100, :2])
    assert err > 0.1, err


def test_update_equals_the_textbook_dense_ekf():
    """One update of a few paired lines against ``K = P Hᵀ S⁻¹``, ``x' = x + K ν``,
    ``P' = (I − K H) P (I − K H)ᵀ + K R Kᵀ`` with dense matrices, to 1e-12."""
    seq = line_seq(20, seed=3)
    ekf = start(seq, 3)
    for k in range(1, 12):
        ekf.predict(seq.motions[k])
    x, P = ekf.pose, ekf.covariance
    frame = seq.frame(11)
    problem = ekf.problem(frame)
    a = true_association(seq.labels[11], problem.landmark_ids)
    a[1] = -1   # leave one candidate out: only the pairs given are used
    ekf.update(a)
    j = np.flatnonzero(a >= 0)
    lines = seq.lines[problem.landmark_ids[j]]
    H = jacobians(x, lines)[0].reshape(-1, 3)
    nu = frame.z[a[j]] - predict(x, lines)
    nu[:, 0] = wrap(nu[:, 0])
    R = np.zeros((2 * len(j), 2 * len(j)))
    for n, i in enumerate(a[j]):
        R[2 * n:2 * n + 2, 2 * n:2 * n + 2] = frame.R[i]
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    IKH = np.eye(3) - K @ H
    x_new = x + K @ nu.ravel()
    x_new[2] = wrap(x_new[2])
    assert np.abs(ekf.pose - x_new).max() < 1e-12
    assert np.abs(ekf.covariance - (IKH @ P @ IKH.T + K @ R @ K.T)).max() < 1e-12 * np.abs(P).max()


def test_motion_step_is_the_planar_ekfs():
    """Prediction only: LineEKF and PlanarEKF (no landmarks) give bit-identical poses and covariances."""
    seq = line_seq(50, seed=1)
    line = start(seq, 1)
    posts = PlanarEKF(EstimatorConfig(), line.pose, P0, np.zeros((0, 2)), [], seq.max_range, seq.fov)
    for k in range(1, 50):
        line.predict(seq.motions[k])
        posts.predict(seq.motions[k])
        np.testing.assert_array_equal(line.pose, posts.pose)
        np.testing.assert_array_equal(line.pose_covariance, posts.pose_covariance)


def test_problem_is_the_joint_prediction_of_the_candidates():
    """Candidates are ``candidate_lines`` of the estimate among the mapped ids; P = H P_pose Hᵀ."""
    seq = line_seq(10, seed=2)
    ids = np.array([0, 2, 4, 5, 7])
    ekf = LineEKF(EstimatorConfig(), seq.poses[3], P0, seq.lines, seq.segments, seq.segment_line,
                  seq.segment_normal, ids, seq.max_range, seq.fov)
    problem = ekf.problem(seq.frame(3))
    seen = candidate_lines(seq.poses[3], seq.segments, seq.segment_line, seq.segment_normal, 8, seq.max_range, seq.fov)
    assert problem.landmark_ids.tolist() == [i for i in ids if seen[i]]
    H = jacobians(seq.poses[3], seq.lines[problem.landmark_ids])[0].reshape(-1, 3)
    np.testing.assert_allclose(problem.P, H @ P0 @ H.T, rtol=1e-12, atol=1e-18)
    assert problem.angular == (0,) and problem.volume == pytest.approx(2 * np.pi * seq.max_range)
    np.testing.assert_array_equal(ekf.landmarks, seq.lines[ids])
    assert ekf.book.ids == ids.tolist() and all(ekf.book.confirmed)
    ekf.update(np.full(problem.n, -1))
    np.testing.assert_array_equal(ekf.pose_covariance, P0)   # no pairing: nothing changes


def test_slam_or_isam2_on_the_lines_track_is_a_user_error():
    seq = line_seq(5, seed=0)
    with pytest.raises(UserError, match="estimator.mode: localisation"):
        get_track(seq.track).estimator(*run_on(seq, estimator=EstimatorConfig(mode="slam")))
    with pytest.raises(UserError, match="lines track's estimator is ekf"):
        get_track(seq.track).estimator(*run_on(seq, estimator=EstimatorConfig(name="isam2")))
    ekf = get_track(seq.track).estimator(*run_on(seq, estimator=EstimatorConfig(), belief=BeliefConfig(map_fraction=0.5)))
    assert isinstance(ekf, LineEKF) and len(ekf.book) == 4


@pytest.mark.parametrize("change, message", [
    (dict(pose=np.zeros(2)), "pose"), (dict(P=np.eye(4)), "P must be"), (dict(ids=[0, 0]), "ids"),
    (dict(ids=[9]), "ids"), (dict(segment_line=[0, 9]), "segment_line"),
    (dict(segment_normal=np.zeros((1, 2))), "normal"),
    (dict(max_range=0.0), "max_range"), (dict(fov=7.0), "fov"), (dict(lines=[[0.0, -1.0], [1.0, 2.0]]), "r_w >= 0")])
def test_bad_constructor_input_is_a_user_error(change, message):
    args = dict(cfg=EstimatorConfig(), pose=np.zeros(3), P=np.eye(3), lines=[[0.0, 1.0], [1.0, 2.0]],
                segments=np.zeros((2, 2, 2)), segment_line=[0, 1], segment_normal=np.ones((2, 2)), ids=[0, 1],
                max_range=5.0, fov=np.pi) | change
    with pytest.raises(UserError, match=message):
        LineEKF(**args)


def test_bad_frame_or_association_is_a_user_error():
    seq = line_seq(5, seed=0)
    ekf = start(seq, 0)
    with pytest.raises(UserError, match="lines frame"):
        ekf.problem(FrameData(np.zeros((2, 3)), np.zeros((2, 3, 3))))
    ekf.problem(seq.frame(0))
    with pytest.raises(UserError, match="association"):
        ekf.update(np.zeros(1, dtype=int))


def test_closed_loop_on_the_lines_track():
    """The registry gives seq.track "lines" ``LinesSensor`` and ``LineEKF``: frames carry the
    extracted lines then ``belief.clutter`` clutter lines (labelled −1), odometry is planar, and MNN
    in the loop on the room (seed 0, 3 clutter lines per frame) stays consistent: measured ANEES
    2.95 over 200 frames (single-run band (2.67, 3.35) for independent frames), ATE 8.7 mm."""
    from assocbench.harness.loop import loop_records
    from assocbench.tracks.lines.loop import LinesSensor

    seq = line_seq(STEPS, seed=0)
    source, run = run_on(seq, "mnn", belief=BeliefConfig(clutter=3), estimator=EstimatorConfig())
    sensor = get_track(seq.track).loop_sensor(source, run)
    assert isinstance(sensor, LinesSensor) and sensor.nees_dof == 3
    data, labels = sensor.frame(4, None)
    m = len(seq.z[4])
    assert data.z.shape == (m + 3, 2) and labels[:m].tolist() == seq.labels[4].tolist() and np.all(labels[m:] == -1)
    assert np.all((data.z[m:, 0] >= -np.pi) & (data.z[m:, 0] < np.pi)) and np.all(data.z[m:, 1] <= seq.max_range)
    records = list(loop_records(source, run))
    nees = np.array([r["nees"] for r in records])
    err = np.array([r["pos_err"] for r in records])
    assert all(r["error"] == "" for r in records) and records[0]["nees_dof"] == 3
    assert 2.0 < nees.mean() < 4.0 and np.sqrt(np.mean(err ** 2)) < 0.02
