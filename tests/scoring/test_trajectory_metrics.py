"""Trajectory accuracy (ATE, rotation error), filter consistency (NEES, ANEES band, divergence)
and TUM files: hand-made cases with known answers, and agreement with evo's ``evo_ape``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from assocbench import UserError
from assocbench.scoring.trajectory import (
    anees,
    anees_band,
    ate_rmse,
    divergence_frame,
    pose_error,
    pose_nees,
    position_errors,
    read_tum,
    rotation_errors_deg,
    rotation_rmse_deg,
    write_tum,
)


def _exp(rotvec) -> np.ndarray:
    return Rotation.from_rotvec(rotvec).as_matrix()


def _truth(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A camera circling a room while turning: stamps, R (camera-to-world), p."""
    t = np.arange(n) * 0.1
    p = np.column_stack([2 * np.cos(t), 2 * np.sin(t), 1.5 + 0.1 * np.sin(3 * t)])
    R = _exp(np.column_stack([0.2 * np.sin(t), 0.1 * t, 1.3 * t]))
    return t, R, p


# ---- accuracy ------------------------------------------------------------------------------

def test_a_constant_offset_gives_its_length_as_ate():
    _, _, p = _truth(20)
    assert ate_rmse(p, p + [0.3, 0.4, 0.0]) == pytest.approx(0.5, abs=1e-12)
    np.testing.assert_allclose(position_errors(p, p + [0.3, 0.4, 0.0]), 0.5, atol=1e-12)


def test_ate_is_the_root_mean_square_not_the_mean():
    p = np.zeros((2, 3))
    assert ate_rmse(p, np.array([[1.0, 0, 0], [0, 2.0, 0]])) == pytest.approx(np.sqrt(2.5), abs=1e-12)


def test_a_nan_frame_makes_the_ate_nan_instead_of_being_skipped():
    _, R, p = _truth(10)
    est = p + 0.1
    est[4] = np.nan
    assert np.isnan(ate_rmse(p, est))
    R_est = R.copy()
    R_est[7] = np.nan
    assert np.isnan(rotation_rmse_deg(R, R_est))


def test_trajectories_of_different_lengths_are_refused():
    _, _, p = _truth(10)
    with pytest.raises(UserError, match="p_true has 10 poses but p_est has 9"):
        ate_rmse(p, p[:9])
    with pytest.raises(UserError, match=r"shape \(N, 3\)"):
        ate_rmse(p, p[:, :2])


@pytest.mark.parametrize("degrees", [30.0, 1e-7, 90.0, 179.9, 180.0])
def test_a_known_rotation_gives_its_angle(degrees):
    _, R, _ = _truth(12)
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    R_est = R @ _exp(np.radians(degrees) * axis)
    np.testing.assert_allclose(rotation_errors_deg(R, R_est), degrees, rtol=1e-9, atol=1e-11)
    assert rotation_rmse_deg(R, R_est) == pytest.approx(degrees, rel=1e-9, abs=1e-11)


# ---- consistency ---------------------------------------------------------------------------

def test_pose_error_follows_the_filter_convention():
    """R_true = R_est · Exp(δθ) with δθ in the body frame, δp = p_true − p_est in the world."""
    _, R, p = _truth(5)
    dp, dtheta = np.array([0.1, -0.2, 0.05]), np.array([0.02, 0.01, -0.03])
    R_true, p_true = R[3] @ _exp(dtheta), p[3] + dp
    np.testing.assert_allclose(pose_error(R_true, p_true, R[3], p[3]), np.r_[dp, dtheta], atol=1e-12)
    assert np.isnan(pose_error(R_true, p_true * np.nan, R[3], p[3])).all()


def _covariance(rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(6, 6)) * np.r_[0.05, 0.05, 0.1, 0.01, 0.01, 0.02]
    return A @ A.T + 1e-6 * np.eye(6)


def test_nees_is_the_mahalanobis_norm_and_averages_to_six_for_errors_drawn_from_p():
    rng = np.random.default_rng([7, 1])
    P = _covariance(rng)
    draws = rng.multivariate_normal(np.zeros(6), P, size=20000)
    nees = np.array([pose_nees(e, P) for e in draws])
    assert pose_nees(draws[0], P) == pytest.approx(draws[0] @ np.linalg.solve(P, draws[0]), rel=1e-9)
    # the mean of 20000 χ²_6 draws has a standard deviation of sqrt(12 / 20000) ≈ 0.025
    assert nees.mean() == pytest.approx(6.0, abs=0.1)
    lo, hi = anees_band(len(nees))
    assert lo < anees(nees) < hi


def test_nees_is_nan_when_the_covariance_cannot_be_used():
    e = np.full(6, 0.1)
    assert np.isnan(pose_nees(e, np.zeros((6, 6))))                    # first SLAM frame
    assert np.isnan(pose_nees(e, np.diag([1.0, 1, 1, 1, 1, -1e-3])))  # indefinite
    assert np.isnan(pose_nees(e, np.diag([1.0, 1, 1, 1, 1, 1e-30])))  # singular to machine precision
    assert np.isnan(pose_nees(e * np.nan, np.eye(6)))
    with pytest.raises(UserError, match="not symmetric"):
        pose_nees(e, np.triu(np.ones((6, 6))) + 6 * np.eye(6))
    with pytest.raises(UserError, match=r"shape \(6, 6\)"):
        pose_nees(e, np.eye(3))


def test_anees_band_for_100_frames_is_the_chi2_600_band_over_100():
    lo, hi = anees_band(100, dof=6, confidence=0.95)
    assert lo == pytest.approx(chi2.ppf(0.025, 600) / 100, rel=1e-12)
    assert hi == pytest.approx(chi2.ppf(0.975, 600) / 100, rel=1e-12)
    assert 5.3 < lo < 5.4 and 6.6 < hi < 6.8     # the values a reader can check in a table
    with pytest.raises(UserError, match="frames must be a whole number"):
        anees_band(0)
    with pytest.raises(UserError, match="confidence must lie strictly between 0 and 1"):
        anees_band(10, confidence=95)


def test_anees_drops_only_the_frames_excluded_by_name():
    nees = np.array([np.nan, 4.0, 6.0, 8.0])
    assert anees(nees, exclude=[0]) == pytest.approx(6.0)
    assert np.isnan(anees(nees))                           # an unexplained NaN is never skipped
    assert np.isnan(anees(np.array([1.0, np.nan, 3.0]), exclude=[0]))
    assert np.isnan(anees([np.nan], exclude=[0]))           # nothing left to average
    with pytest.raises(UserError, match=r"outside 0..3"):
        anees(nees, exclude=[4])
    with pytest.raises(UserError, match="frame indices"):
        anees(nees, exclude=[True, False, False, False])


def test_divergence_is_the_start_of_the_first_long_enough_excursion():
    bound = chi2.ppf(0.999, 6)                          # ≈ 22.46
    low, high = 0.5 * bound, 2.0 * bound
    seq = [low] * 5 + [high] * 3 + [low] * 2 + [high] * 4 + [np.nan] + [high] * 6
    # frames 5-7: too short; 10-13: broken by the NaN at 14; 15-20: six frames above
    assert divergence_frame(seq, run=5) == 15
    assert divergence_frame(seq, run=3) == 5
    assert divergence_frame(seq[:19], run=5) == -1       # cut short by the end of the run
    assert divergence_frame([low] * 30) == -1
    assert divergence_frame([bound] * 10) == -1           # on the bound is not above it
    assert divergence_frame([high] * 2, run=5) == -1


# ---- TUM files -----------------------------------------------------------------------------

def test_tum_round_trip_keeps_every_pose(tmp_path):
    stamps, R, p = _truth(40)
    stamps = stamps + 1.7e9                                # a Unix time keeps its sub-µs digits
    write_tum(tmp_path / "traj.txt", stamps, R, p)
    lines = (tmp_path / "traj.txt").read_text().splitlines()
    assert lines[0].startswith("#") and len(lines) == 41 and all(len(x.split(" ")) == 8 for x in lines[1:])
    s2, R2, p2 = read_tum(tmp_path / "traj.txt")
    np.testing.assert_array_equal(s2, stamps)
    np.testing.assert_array_equal(p2, p)
    np.testing.assert_allclose(R2, R, atol=1e-14)
    assert [f.name for f in tmp_path.iterdir()] == ["traj.txt"]   # no temporary file left


def test_tum_writer_refuses_what_would_be_silently_wrong(tmp_path):
    stamps, R, p = _truth(5)
    target = tmp_path / "t.txt"
    with pytest.raises(UserError, match="pose 2 is not a rotation"):
        write_tum(target, stamps, np.concatenate([R[:2], 2 * R[2:3], R[3:]]), p)
    with pytest.raises(UserError, match="p of pose 1 is not finite"):
        write_tum(target, stamps, R, np.where(np.arange(5)[:, None] == 1, np.nan, p))
    with pytest.raises(UserError, match="stamps must strictly increase"):
        write_tum(target, stamps[::-1], R, p)
    with pytest.raises(UserError, match="same N poses"):
        write_tum(target, stamps[:4], R, p)
    assert not any(tmp_path.iterdir())


def test_tum_reader_names_the_bad_line(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("# header\n0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 1\n")
    with pytest.raises(UserError, match="bad.txt line 3: expected 8 finite numbers"):
        read_tum(path)
    with pytest.raises(UserError, match="cannot read TUM file"):
        read_tum(tmp_path / "missing.txt")


# ---- agreement with evo --------------------------------------------------------------------

def _evo_ape(tmp_path: Path, relation: str) -> tuple[float, np.ndarray]:
    """``evo_ape tum truth.txt estimate.txt -r relation`` (no alignment): rmse and per-frame errors."""
    exe = Path(sys.executable).with_name("evo_ape")
    if not exe.exists():
        pytest.skip(f"evo is importable but {exe} is missing; install evo into this environment")
    out = tmp_path / f"ape_{relation}.zip"
    env = {**os.environ, "HOME": str(tmp_path), "MPLBACKEND": "Agg"}   # evo writes ~/.evo settings
    done = subprocess.run([str(exe), "tum", "truth.txt", "estimate.txt", "-r", relation,
                           "--save_results", str(out), "--no_warnings"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr + done.stdout
    with zipfile.ZipFile(out) as z:
        rmse = json.loads(z.read("stats.json"))["rmse"]
        with z.open("error_array.npy") as f:
            errors = np.load(f)
    return rmse, errors


def test_evo_ape_reports_our_ate_and_rotation_rmse(tmp_path):
    pytest.importorskip("evo")
    stamps, R, p = _truth(300)
    rng = np.random.default_rng([7, 2])
    p_est = p + np.cumsum(rng.normal(0, 0.01, (len(p), 3)), axis=0)        # drifting estimate
    dtheta = np.cumsum(rng.normal(0, 0.005, (len(p), 3)), axis=0)
    dtheta[-3:] = [[0, 0, 3.0], [0, 3.1, 0], [3.14, 0, 0]]                  # large errors, near π
    R_est = R @ _exp(dtheta)
    write_tum(tmp_path / "truth.txt", stamps, R, p)
    write_tum(tmp_path / "estimate.txt", stamps, R_est, p_est)

    evo_ate, evo_position_errors = _evo_ape(tmp_path, "trans_part")
    evo_rot, evo_rotation_errors = _evo_ape(tmp_path, "angle_deg")
    assert evo_ate == pytest.approx(ate_rmse(p, p_est), abs=1e-6)
    assert evo_rot == pytest.approx(rotation_rmse_deg(R, R_est), abs=1e-6)
    np.testing.assert_allclose(evo_position_errors, position_errors(p, p_est), atol=1e-6)
    np.testing.assert_allclose(evo_rotation_errors, rotation_errors_deg(R, R_est), atol=1e-6)
    assert evo_ate > 0.05 and evo_rot > 1.0        # the comparison is about real errors, not zeros


def test_anees_is_the_mean_nees_and_its_unit_says_so_not_per_dof():
    """ANEES is not divided by the dof: a consistent 3-dof filter's is near 3, and no unit or
    report text may tell the reader to expect 1."""
    from assocbench.harness.report.columns import CATALOGUE
    from assocbench.scoring.units import unit_of

    nees = np.full(200, 3.0)
    lo, hi = anees_band(200, 3)
    assert anees(nees) == 3.0 and lo < 3.0 < hi
    assert "/ dof" not in unit_of("anees") and "dof" in unit_of("anees")
    for key in ("anees_lo", "anees_hi"):   # the band's ends say they are its ends
        assert "/ dof" not in unit_of(key) and "95 % band" in unit_of(key)
    meaning = next(c.meaning for c in CATALOGUE if c.key == "anees")
    assert "divided by the pose" not in meaning and "1 is a consistent" not in meaning
