"""One failing back end never takes another's results with it (issue 26 item 15): an exception
that GTSAM's iSAM2 raises during a run (in ``update``, ``predict``, or a marginal for the problem)
ends only that run, as failed frames counted in ``failures`` with the error, and the run is not ok;
in a leaderboard with both back ends the EKF rows of the same scene and seed keep their results."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.loop import loop_records
from assocbench.scoring.aggregate import OK, summarize

gtsam = pytest.importorskip("gtsam")
ROOT = str(Path(__file__).resolve().parents[2])   # the repository

FRAMES, FAIL_AT = 12, 5
GTSAM_ERROR = "Indeterminant linear system detected while working near variable 8646911284551352325 (Symbol: x5)."


def inject(monkeypatch, name: str) -> None:
    """Make ``PlanarISAM2.<name>`` raise GTSAM's error from frame ``FAIL_AT`` on."""
    from assocbench.estimators.planar_isam2 import PlanarISAM2

    real = getattr(PlanarISAM2, name)

    def failing(self, *args, **kwargs):
        if self.frame >= FAIL_AT:
            raise RuntimeError(GTSAM_ERROR)
        return real(self, *args, **kwargs)
    monkeypatch.setattr(PlanarISAM2, name, failing)


def isam2_spec(frames: int = FRAMES):
    cfg = load_run_config(None, ["estimator.name=isam2"], method="jcbb", scene="park", trajectory=None,
                          frames=frames, seed=0, loop=True)
    return run_spec(cfg)


@pytest.mark.parametrize("where", ["_flush", "joint_covariance", "predict"])   # update, problem, odometry
def test_a_back_end_exception_fails_the_rest_of_its_run_only(monkeypatch, where):
    spec = isam2_spec()
    inject(monkeypatch, where)
    frames = pd.DataFrame(loop_records(spec.source, spec.with_method("oracle", {})))
    assert list(frames["frame"]) == list(range(FRAMES))
    failed = frames["error"] != ""
    first = int(failed.to_numpy().argmax())
    assert FAIL_AT - 1 <= first <= FAIL_AT + 1 and failed[first:].all() and not failed[:first].any()
    assert frames["error"].iloc[-1].startswith(f"EstimatorFailed at frame {first}: RuntimeError: Indeterminant")
    s = summarize(frames)
    assert s["failures"] == FRAMES - first and s["frames"] == FRAMES
    assert s["status"] == f"{FRAMES - first}/{FRAMES} frames failed; the estimator failed at frame {first}, " \
                          "so no later frame was measured"
    assert s["map_size"] > 0   # the map the estimator had when it failed
    assert pd.isna(s["ate_rmse"])   # not measured: no pose after the failure


SUITE = f"""
base: {{loop: true, frames: {FRAMES}}}
scenes: [park]
difficulties:
  easy: {{}}
backends:
  ekf: {{estimator: {{name: ekf}}}}
  isam2: {{estimator: {{name: isam2}}}}
methods: [oracle]
seeds: [0]
"""

# a script whose top level (which a forkserver's workers import too) breaks iSAM2's update
LAUNCHER = f"""
import sys
from assocbench.estimators.planar_isam2 import PlanarISAM2

real = PlanarISAM2._flush


def failing(self):
    if self.frame >= {FAIL_AT}:
        raise RuntimeError({GTSAM_ERROR!r})
    return real(self)


PlanarISAM2._flush = failing
if __name__ == "__main__":
    from assocbench.cli.main import main
    sys.exit(main(sys.argv[1:]))
"""


def test_a_leaderboard_keeps_the_ekf_rows_when_isam2_fails(tmp_path, jobs=1):
    (tmp_path / "suite.yaml").write_text(SUITE)
    (tmp_path / "launch.py").write_text(textwrap.dedent(LAUNCHER))
    out = tmp_path / f"out{jobs}"
    proc = subprocess.run([sys.executable, str(tmp_path / "launch.py"), "leaderboard", "--suite",
                           str(tmp_path / "suite.yaml"), "--out", str(out), "--jobs", str(jobs)],
                          capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": ROOT})
    assert proc.returncode == 1, proc.stderr   # rows that are not ok: exit 1, not a crash
    assert "Traceback" not in proc.stderr
    board = pd.read_csv(out / "leaderboard.csv")
    ekf = board[board["scenario"] == "park/easy-ekf"]
    isam2 = board[board["scenario"] == "park/easy-isam2"]
    assert len(ekf) == 1 and len(isam2) == 1
    assert (ekf["status"] == OK).all() and ekf["ate_rmse"].notna().all()
    assert (isam2["status"] != OK).all()
    assert isam2["status"].str.contains(f"the estimator failed at frame {FAIL_AT}").all()



def test_a_replay_for_pictures_ends_where_the_estimator_failed(room_sequence, monkeypatch):
    """``render --loop`` replays the run: its frames end at the estimator's failure, with no traceback."""
    from assocbench.harness.loop_replay import replay_run
    from assocbench.tracks.camera.ekf import CameraEKF

    real, calls = CameraEKF.predict, []

    def failing(self, motion):
        calls.append(1)
        if len(calls) >= 3:   # the prediction into frame 3
            raise ValueError("array must not contain infs or NaNs")
        return real(self, motion)
    monkeypatch.setattr(CameraEKF, "predict", failing)
    cfg = load_run_config(None, [], method="oracle", scene="room", trajectory=None, frames=len(room_sequence),
                          seed=0, loop=True)
    n = len(room_sequence)   # a run whose every frame failed: the replay only predicts
    records = pd.DataFrame({"frame": range(n), "association": [None] * n, "error": ["failed"] * n})
    assert [f.k for f in replay_run(run_spec(cfg), records)] == [0, 1, 2]
