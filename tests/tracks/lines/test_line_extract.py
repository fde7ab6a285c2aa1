"""The polar line fit (lecture example, covariance against Monte Carlo, conventions) and the three
line extractors on a synthetic room (recall, precision, accuracy against the fit's own Σ, labels)."""

from __future__ import annotations

import numpy as np
import pytest
from line_synth import robot_lines, room, synth_scan
from scipy.optimize import minimize

from assocbench.errors import UserError
from assocbench.models.range_bearing import wrap
from assocbench.sim.scan import Scan
from assocbench.tracks.lines.extract import LineDetections, extract_lines, label_lines
from assocbench.tracks.lines.polar_fit import fit_polar_line
from assocbench.tracks.lines.settings import LineExtractorConfig

# Lecture 24's numeric example: 17 beams at 0°, 5°, ..., 80°.
LECTURE_RHO = np.array([0.5197, 0.4404, 0.4850, 0.4222, 0.4132, 0.4371, 0.3912, 0.3949, 0.3919, 0.4276,
                        0.4075, 0.3956, 0.4053, 0.4752, 0.5032, 0.5273, 0.4879])
LECTURE_BETA = np.deg2rad(np.arange(0.0, 81.0, 5.0))
METHODS = ("polar", "split_merge", "ransac")


def cost(alpha: float, r: float, w: np.ndarray) -> float:
    """The lecture's cost ``S = Σ w_i (ρ_i cos(β_i − α) − r)²`` on its table."""
    return float(np.sum(w * (LECTURE_RHO * np.cos(LECTURE_BETA - alpha) - r) ** 2))


def numerical_minimum(w: np.ndarray) -> np.ndarray:
    """Independent minimisation of ``cost`` (Nelder-Mead from several starts, tight tolerances)."""
    best = None
    for a0 in np.deg2rad([0.0, 30.0, 60.0, 120.0]):
        res = minimize(lambda x: cost(x[0], x[1], w), [a0, 0.3], method="Nelder-Mead",
                       options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 20000})
        best = res if best is None or res.fun < best.fun else best
    return best.x


@pytest.mark.parametrize("weights, alpha_deg, r", [("uniform", 37.96, 0.3999), ("proportional", 38.01, 0.3980)])
def test_lecture_example_is_the_minimum_of_the_cost(weights, alpha_deg, r):
    """Our closed form gives α = 37.96°, r = 0.3999 m on the lecture's table (σ ∝ ρ, "uncertainty
    proportional to the distance": 38.01°, 0.3980 m) and agrees with a numerical minimisation to
    0.01°. The lecture prints α = 37.36°, r = 0.4: that is not the minimum of its own cost on the
    printed table (S is larger there, whatever r), most likely a typo (37.96 → 37.36)."""
    sigma = 1.0 if weights == "uniform" else LECTURE_RHO
    a, rr, cov = fit_polar_line(LECTURE_RHO, LECTURE_BETA, sigma)
    w = np.ones(17) / np.broadcast_to(sigma, 17) ** 2
    x = numerical_minimum(w)
    assert np.rad2deg(a) == pytest.approx(alpha_deg, abs=0.005) and rr == pytest.approx(r, abs=5e-5)
    assert abs(np.rad2deg(wrap(a - x[0]))) < 0.01 and rr == pytest.approx(x[1], abs=1e-6)
    printed = np.deg2rad(37.36)
    best_r_at_printed = np.sum(w * LECTURE_RHO * np.cos(LECTURE_BETA - printed)) / w.sum()
    assert cost(printed, best_r_at_printed, w) > cost(a, rr, w) * 1.005
    assert cost(printed, 0.4, w) > cost(a, rr, w)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def line_beams(alpha: float, r: float, length: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """True ranges and bearings of n points spread evenly along a segment of the line (α, r)."""
    normal = np.array([np.cos(alpha), np.sin(alpha)])
    t = np.linspace(-length / 2, length / 2, n)
    p = r * normal + t[:, None] * np.array([-normal[1], normal[0]])
    return np.hypot(p[:, 0], p[:, 1]), np.arctan2(p[:, 1], p[:, 0])


@pytest.mark.parametrize("alpha, r, length, n, sigma_beta", [
    (0.3, 2.0, 1.0, 30, 0.0),            # 1 m line at 2 m
    (-1.2, 5.0, 4.0, 50, 0.0),           # 4 m line at 5 m
    (2.5, 8.0, 0.5, 10, 0.0),            # short 0.5 m line at 8 m
    (np.pi - 0.01, 3.0, 3.0, 40, 0.0),   # a line near α = ±π
    (0.8, 1.5, 2.0, 20, np.deg2rad(0.5)),  # with bearing noise too
])
@pytest.mark.parametrize("shift", [0.0, 1.0])
def test_covariance_matches_monte_carlo(alpha, r, length, n, sigma_beta, shift):
    """Σ_(α,r) by first-order propagation against 4000 noisy fits: σ_α and σ_r within 10 %, the
    correlation within 0.1; ``shift``: the segment slid along its line by that many lengths
    (an oblique view, α and r correlated).

    The one place first order falls short: a short line far away seen head-on (0.5 m at 8 m, 10
    beams, σ_α = 1.1°). There ``∂r/∂α = 0`` and r moves by ``−r δα²/2`` (the centroid stays, the
    line turns about it), so σ_r² gains ``r² σ_α⁴ / 2``: the Monte Carlo σ_r is 19 % above the
    first-order one and within 3 % of the second-order sum (checked below)."""
    normal = np.array([np.cos(alpha), np.sin(alpha)])
    t = np.linspace(-length / 2, length / 2, n) + shift * length
    p = r * normal + t[:, None] * np.array([-normal[1], normal[0]])
    rho, beta = np.hypot(p[:, 0], p[:, 1]), np.arctan2(p[:, 1], p[:, 0])
    sigma = 0.01
    _, _, cov = fit_polar_line(rho, beta, sigma, sigma_beta)
    rng = np.random.default_rng([15, n])
    fits = np.array([fit_polar_line(rho + sigma * rng.standard_normal(n), beta + sigma_beta * rng.standard_normal(n),
                                    sigma)[:2] for _ in range(4000)])
    err = np.column_stack([wrap(fits[:, 0] - alpha), fits[:, 1] - r])
    mc = np.cov(err.T)
    expected = np.sqrt(np.diag(cov))
    if r / length > 10 and shift == 0:
        expected[1] = np.sqrt(cov[1, 1] + r ** 2 * cov[0, 0] ** 2 / 2)
        assert np.sqrt(mc[1, 1] / cov[1, 1]) > 1.1
    assert expected == pytest.approx(np.sqrt(np.diag(mc)), rel=0.10)
    corr = lambda c: c[0, 1] / np.sqrt(c[0, 0] * c[1, 1])  # noqa: E731
    assert abs(corr(cov) - corr(mc)) < 0.1


def test_covariance_matches_central_differences():
    """The implicit-function Jacobian ∂(α, r)/∂ρ equals central differences of the closed form:
    Σ from finite differences (J diag(σ²) Jᵀ) within 1e-4 relative."""
    rho, beta = line_beams(0.7, 2.5, 2.0, 25)
    rho = rho + 0.02 * np.random.default_rng(3).standard_normal(25)   # residuals: the d terms matter
    sigma = 0.01 * (1 + np.arange(25) / 25)
    _, _, cov = fit_polar_line(rho, beta, sigma)
    J = np.empty((2, 25))
    for i in range(25):
        h = np.zeros(25)
        h[i] = 1e-6
        plus, minus = fit_polar_line(rho + h, beta, sigma)[:2], fit_polar_line(rho - h, beta, sigma)[:2]
        J[:, i] = [wrap(plus[0] - minus[0]) / 2e-6, (plus[1] - minus[1]) / 2e-6]
    assert cov == pytest.approx(J @ np.diag(sigma ** 2) @ J.T, rel=1e-4, abs=1e-14)


@pytest.mark.parametrize("alpha", [np.pi - 1e-3, -np.pi + 1e-3, -np.pi, 0.0, 1.0, -2.0])
def test_fit_keeps_r_positive_and_wraps_alpha(alpha):
    """r >= 0 and α ∈ [−π, π) for every orientation, including a wall behind the sensor at α ≈ ±π."""
    rho, beta = line_beams(alpha, 1.7, 1.5, 15)
    a, r, _ = fit_polar_line(rho, beta, 0.01)
    assert -np.pi <= a < np.pi and r > 0
    assert abs(wrap(a - alpha)) < 1e-9 and r == pytest.approx(1.7, abs=1e-9)


def test_fit_refuses_bad_input():
    with pytest.raises(UserError, match="at least 2 distinct"):
        fit_polar_line([1.0], [0.0], 0.01)
    with pytest.raises(UserError, match="sigma_rho"):
        fit_polar_line([1.0, 1.0], [0.0, 0.1], 0.0)


POSES = [np.array([2.0, 1.5, 0.0]), np.array([1.2, 3.1, 2.5]), np.array([4.9, 0.9, -1.0])]


def check_detections(det: LineDetections, labels: np.ndarray, beam_labels: np.ndarray, world, pose, cfg,
                     expected: set[int]) -> None:
    """Recall of ``expected``, no false line, α/r within 4σ of the fit's Σ, no line across a corner."""
    found = set(labels.tolist())
    assert expected <= found, f"missed map lines {expected - found}"
    assert -1 not in found, "a false line"
    truth = robot_lines(world, pose)
    for k, lab in enumerate(labels):
        err = np.array([wrap(det.z[k, 0] - truth[lab, 0]), det.z[k, 1] - truth[lab, 1]])
        assert np.all(np.abs(err) <= 4 * np.sqrt(np.diag(det.R[k]))), (k, lab, err, np.sqrt(np.diag(det.R[k])))
        assert -np.pi <= det.z[k, 0] < np.pi and det.z[k, 1] >= 0
        on_wall = beam_labels[det.beams[k]] == lab
        assert on_wall.sum() >= len(on_wall) - 2, "a line spans a corner"
        face = world.faces[world.face_line == lab]
        c, s = np.cos(pose[2]), np.sin(pose[2])
        ends_world = det.endpoints[k] @ np.array([[c, s], [-s, c]]) + pose[:2]
        lo, hi = face.reshape(-1, 2).min(axis=0) - 0.05, face.reshape(-1, 2).max(axis=0) + 0.05
        assert np.all((ends_world >= lo) & (ends_world <= hi)), "an end point beyond the wall"


def extractable(beam_labels: np.ndarray, min_points: int) -> set[int]:
    """Map lines with min_points beams and a couple to spare (the beam at a corner may go either way)."""
    count = np.bincount(beam_labels[beam_labels >= 0])
    return set(np.flatnonzero(count >= min_points + 2).tolist())


@pytest.mark.parametrize("method", ["split_merge", "ransac"])
@pytest.mark.parametrize("pose_index", range(len(POSES)))
@pytest.mark.parametrize("seed", [0, 1])
def test_extraction_in_the_closed_room(method, pose_index, seed):
    """Closed 6 x 4 m room with a pillar: every wall face with enough beams is found, nothing else."""
    world, pose = room(), POSES[pose_index]
    scan, beam_labels = synth_scan(world, pose, seed=seed)
    cfg = LineExtractorConfig(method=method)
    det = extract_lines(scan, 0.01, cfg)
    labels = label_lines(det, beam_labels, cfg.min_share)
    check_detections(det, labels, beam_labels, world, pose, cfg, extractable(beam_labels, cfg.min_points))


def test_polar_baseline_fails_at_corners_only():
    """Breakpoints alone cannot cut a corner: in the closed room the polar baseline keeps no
    line (every chain turns a corner and fails the residual test) rather than a false one; with
    open corners it finds the four walls."""
    pose = POSES[0]
    cfg = LineExtractorConfig(method="polar")
    scan, beam_labels = synth_scan(room(), pose)
    assert len(extract_lines(scan, 0.01, cfg)) == 0
    world = room(corner_gap=0.3)
    scan, beam_labels = synth_scan(world, pose)
    det = extract_lines(scan, 0.01, cfg)
    check_detections(det, label_lines(det, beam_labels, 0.8), beam_labels, world, pose, cfg, {0, 1, 2, 3})


@pytest.mark.parametrize("method", METHODS)
def test_wall_across_the_seam_stays_whole(method):
    """Beam 0 (the heading) points at the middle of a wall: the wall is one line, not two."""
    world, pose = room(pillar=False, corner_gap=0.3), np.array([3.0, 2.0, 0.0])
    scan, beam_labels = synth_scan(world, pose)
    det = extract_lines(scan, 0.01, LineExtractorConfig(method=method))
    labels = label_lines(det, beam_labels, 0.8)
    assert sorted(labels.tolist()) == [0, 1, 2, 3]
    seam = det.beams[int(np.flatnonzero(labels == 1)[0])]
    assert 0 in seam and 359 in seam and len(seam) >= (beam_labels == 1).sum() - 2


def test_split_merge_merges_across_an_occluder():
    """A pillar hides the middle of a wall: split-and-merge gives one line for both visible pieces."""
    world, pose = room(), np.array([2.0, 2.6, 0.0])        # the pillar between the robot and x = 6
    scan, beam_labels = synth_scan(world, pose)
    pieces = np.flatnonzero(np.diff(np.flatnonzero(beam_labels == 1)) > 1)
    assert len(pieces) == 1                                  # the wall is seen in two pieces
    det = extract_lines(scan, 0.01, LineExtractorConfig(min_points=8))   # 360 beams: a piece has ~10
    labels = label_lines(det, beam_labels, 0.8)
    assert (labels == 1).sum() == 1
    ransac = extract_lines(scan, 0.01, LineExtractorConfig(method="ransac", min_points=8))
    assert (label_lines(ransac, beam_labels, 0.8) == 1).sum() == 2   # one line per contiguous piece


@pytest.mark.parametrize("method", METHODS)
def test_interspersed_nan_ranges_are_skipped(method):
    """Every 7th beam without return: the same walls, no NaN beam in any line."""
    world, pose = room(corner_gap=0.3), POSES[0]
    scan, beam_labels = synth_scan(world, pose)
    scan.ranges[::7] = np.nan
    det = extract_lines(scan, 0.01, LineExtractorConfig(method=method))
    labels = label_lines(det, beam_labels, 0.8)
    assert {0, 1, 2, 3} <= set(labels.tolist()) and -1 not in labels
    assert all(np.isfinite(scan.ranges[b]).all() for b in det.beams)


def test_ransac_is_reproducible():
    scan, _ = synth_scan(room(), POSES[1])
    cfg = LineExtractorConfig(method="ransac")
    a, b = extract_lines(scan, 0.01, cfg), extract_lines(scan, 0.01, cfg)
    assert np.array_equal(a.z, b.z)
    c = extract_lines(scan, 0.01, cfg, np.random.default_rng([4, 2]))
    assert len(c) == len(a)


@pytest.mark.parametrize("method", METHODS)
def test_empty_scans_give_empty_detections(method):
    """All beams at max range (NaN), or fewer returns than a line needs: empty results."""
    angles = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    cfg = LineExtractorConfig(method=method)
    for ranges in (np.full(360, np.nan), np.where(np.arange(360) < 5, 2.0, np.nan)):
        det = extract_lines(Scan(angles, ranges, np.full(360, -1)), 0.01, cfg)
        assert len(det) == 0 and det.z.shape == (0, 2) and det.R.shape == (0, 2, 2)
        assert det.endpoints.shape == (0, 2, 2) and det.beams == []
        assert label_lines(det, np.full(360, -1), 0.8).shape == (0,)


@pytest.mark.parametrize("settings, message", [
    ({"min_points": 2}, "lines.min_points"), ({"method": "hough"}, "lines.method"),
    ({"min_length": -1.0}, "lines.min_length"), ({"ransac_iterations": 0}, "lines.ransac_iterations"),
    ({"split_distance": 0.0}, "lines.split_distance"), ({"min_share": 0.4}, "lines.min_share"),
])
def test_bad_config_is_one_line(settings, message):
    with pytest.raises(UserError, match=message) as err:
        LineExtractorConfig(**settings)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("sigma", [0.0, -0.01, float("nan")])
def test_bad_sigma_is_one_line(sigma):
    scan, _ = synth_scan(room(), POSES[0])
    with pytest.raises(UserError, match="sigma_range"):
        extract_lines(scan, sigma, LineExtractorConfig())


def test_label_lines_majority_and_share():
    det = LineDetections(np.zeros((3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2, 2)),
                         [np.arange(0, 10), np.arange(10, 20), np.arange(20, 30)])
    beam_labels = np.concatenate([np.full(10, 4), np.r_[np.full(7, 2), np.full(3, 1)], np.r_[np.full(9, -1), 5]])
    assert label_lines(det, beam_labels, 0.8).tolist() == [4, -1, -1]
    assert label_lines(det, beam_labels, 0.7).tolist() == [4, 2, -1]
