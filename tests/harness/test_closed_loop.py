"""The closed loop: an EKF-SLAM fed by each method's own pairings (harness.loop, estimators/).

Figures asserted here are measured on the shipped room (see the README's closed-loop section):
the oracle keeps the filter consistent, one wrong pairing shows at once in the pose error and
NEES, and bad settings or bad answers never end in a traceback or a silent good score.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from runs import run_on

from assocbench.belief.config import BeliefConfig
from assocbench.estimators.config import EstimatorConfig
from assocbench.harness.loop import ClosedLoop, loop_records
from assocbench.harness.runner import call_method
from assocbench.scoring.aggregate import summarize
from assocbench.scoring.trajectory import ate_rmse, read_tum
from tests.cli.test_cli import run_cli

FRAMES = 100


@pytest.fixture(scope="module")
def room100(private_cache):
    from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence

    return load_sequence(SequenceSpec(scene="room", frames=FRAMES))


@pytest.fixture(scope="module")
def room_rgbd(private_cache):
    from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence

    return load_sequence(SequenceSpec(scene="room", frames=FRAMES, feature_depth=True))


def run_loop(seq, method="oracle", seed=0, est=None, belief=None, time_limit_s=math.inf, **kw) -> pd.DataFrame:
    source, run = run_on(seq, method, seed=seed, belief=belief or BeliefConfig(), estimator=est or EstimatorConfig(),
                         time_limit_s=time_limit_s)
    return pd.DataFrame(list(loop_records(source, run, **kw)))


def closed_loop(seq) -> ClosedLoop:
    """The closed loop of the oracle on ``seq`` with the default belief and estimator."""
    return ClosedLoop(*run_on(seq, belief=BeliefConfig(), estimator=EstimatorConfig()))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_oracle_localisation_is_consistent(room100, seed):
    """With the true association the filter's pose NEES averages near its 6 dof (measured 5.2-5.7
    over 100-200 frames; one run's frames are correlated, so the tolerance is wider than the
    independent-frame χ² band), the ATE is a few centimetres and nothing diverges."""
    s = summarize(run_loop(room100, seed=seed))
    assert s["status"] == "ok" and s["precision"] == 1.0 and s["recall"] == 1.0
    assert 4.8 < s["anees"] < 7.2, s["anees"]
    assert s["ate_rmse"] < 0.05 and s["rot_rmse_deg"] < 1.0
    assert s["diverged_at"] == -1 and s["duplicates"] == 0 and s["false_landmarks"] == 0


def test_oracle_slam_is_consistent(room_rgbd):
    """slam mode: the map starts empty and grows from RGB-D features; with the true association
    the filter stays near consistent (ANEES measured 7.7 over these 100 frames, 6.0 over 200:
    one run's frames are correlated) and makes no false landmark."""
    s = summarize(run_loop(room_rgbd, est=EstimatorConfig(mode="slam")))
    assert s["status"] == "ok"
    assert 4.5 < s["anees"] < 9.0, s["anees"]
    assert s["ate_rmse"] < 0.15 and s["map_size"] >= 10
    assert s["false_landmarks"] == 0 and s["diverged_at"] == -1


def test_one_wrong_pairing_shows_in_pose_error_and_nees(room100):
    """Pair one landmark with another landmark's feature at frame 30: pose error and NEES jump at
    that frame by a clear margin; the oracle's do not."""
    bad_frame = 30

    def runs(wrong: bool) -> pd.DataFrame:
        loop, rows = closed_loop(room100), []
        for k in range(bad_frame + 3):
            def decide(problem, truth, k=k):
                a = truth.association.copy()
                if wrong and k == bad_frame:
                    paired = np.flatnonzero(a >= 0)
                    a[paired[0]], a[paired[-1]] = a[paired[-1]], a[paired[0]]   # two landmarks swap features
                return a, 0.0, {}, ""
            rows.append(loop.frame(k, decide))
        return pd.DataFrame(rows)

    good, bad = runs(False), runs(True)
    assert np.array_equal(good["pos_err"][:bad_frame], bad["pos_err"][:bad_frame])
    before, after = bad["nees"][bad_frame - 1], bad["nees"][bad_frame]
    assert after > 5 * max(before, 1.0) and after > 30, (before, after)
    assert bad["pos_err"][bad_frame] > 2 * good["pos_err"][bad_frame]
    assert good["nees"][bad_frame] < 22.46   # the oracle stays below the 99.9 % bound


def test_same_seed_same_numbers_and_replay_resumes_exactly(room100):
    """Bit-for-bit reproducible (timing aside); a worker resuming at frame k from the recorded
    associations of frames < k rebuilds the same filter."""
    a = run_loop(room100, method="mnn")
    b = run_loop(room100, method="mnn")
    cols = [c for c in a.columns if c != "runtime_s"]
    pd.testing.assert_frame_equal(a[cols], b[cols])
    replay = {k: (a["association"][k], a["error"][k]) for k in range(40)}
    resumed = run_loop(room100, method="mnn", first=40, replay=replay)
    pd.testing.assert_frame_equal(resumed[cols].reset_index(drop=True), a[cols][40:].reset_index(drop=True))


class _Broken:
    """A method whose answer is invalid on frame 5 (a feature used twice), fine otherwise."""

    def __init__(self):
        from assocbench.associators.registry import make_associator
        self.inner, self.calls = make_associator("jcbb"), 0

    def associate(self, problem):
        a = self.inner.associate(problem)
        self.calls += 1
        if self.calls == 6 and problem.n >= 2:
            a = np.full(problem.n, 0)
        return a


def test_invalid_association_is_a_failed_frame_and_does_not_touch_the_filter(room100):
    method = _Broken()
    loop, rows = closed_loop(room100), []
    for k in range(8):
        cov_before = np.trace(loop.filter.pose_covariance)
        rows.append(loop.frame(k, lambda problem, truth: call_method(method, problem)))
        if k == 5:
            assert rows[-1]["error"].startswith("ValueError")
            assert np.trace(loop.filter.pose_covariance) > cov_before   # predicted, not updated
    s = summarize(pd.DataFrame(rows))
    assert s["failures"] == 1 and s["status"].startswith("1/8 frames failed")


def test_zero_or_nan_depth_makes_no_landmark():
    from assocbench.estimators.base import FrameData
    from assocbench.models.camera import Intrinsics
    from assocbench.tracks.camera.ekf import CameraEKF

    K = Intrinsics.from_fovy(640, 480, 60)
    ekf = CameraEKF(K, EstimatorConfig(mode="slam"), np.eye(3), np.zeros(3), np.zeros((6, 6)), np.zeros((0, 3)),
                    np.zeros((0, 3)), np.zeros(0, np.int64))
    z = np.array([[100.0, 100.0], [200.0, 200.0], [300.0, 250.0], [320.0, 240.0]])
    frame = FrameData(z, np.repeat(np.eye(2)[None], 4, axis=0), np.array([0.0, np.nan, -1.0, 2.0]))
    made = ekf.initialise(frame, np.arange(4))
    assert [i for _, i in made] == [3]
    np.testing.assert_allclose(ekf.landmarks[0], [(320 - K.cx) / K.f * 2.0, (240 - K.cy) / K.f * 2.0, 2.0])


@pytest.mark.parametrize("setting, message", [
    ("estimator.mode=mapping", "estimator.mode must be one of localisation, slam"),
    ("estimator.name=ukf", "estimator.name must be one of ekf"),
    ("estimator.odometry_sigma_translation=-0.1", "estimator.odometry_sigma_translation must be a finite number"),
    ("estimator.odometry_sigma_rotation=.nan", "estimator.odometry_sigma_rotation must be a finite number"),
])
def test_bad_estimator_settings_are_one_line_errors(setting, message, tmp_path):
    proc = run_cli("run", "--method", "jcbb", "--loop", "--frames", "3", "--set", setting, "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_oracle_only_in_the_loop(tmp_path):
    proc = run_cli("run", "--method", "oracle", "--frames", "3", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "use it with --loop" in proc.stderr and "Traceback" not in proc.stderr


def test_run_loop_writes_tum_files_that_give_our_ate(tmp_path, room100):
    out = tmp_path / "run"
    proc = run_cli("run", "--method", "jcbb", "--loop", "--frames", "12", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    summary = pd.read_csv(out / "summary.csv")
    _, _, p_true = read_tum(out / "truth.txt")
    stamps, _, p_est = read_tum(out / "estimate.txt")
    assert len(stamps) == 12 and summary["loop"][0] == "localisation"
    assert ate_rmse(p_true, p_est) == pytest.approx(summary["ate_rmse"][0], rel=1e-6)
