"""Correspondence truth of the dense track: what counts as a true pair, a partner, precision, recall."""

import numpy as np
import pytest

from assocbench.models.camera import Intrinsics
from assocbench.models.depth_frame import DepthFrame, normal_map, vertex_map
from assocbench.tracks.dense.metrics import has_partner, relative_pose_error, score_correspondences


def wall_frame(z: float = 2.0, w: int = 40, h: int = 30) -> DepthFrame:
    """A camera at the origin (identity pose) facing a wall at depth ``z``: left half geom 1, right half geom 2."""
    K = Intrinsics.from_fovy(w, h, 45.0)
    depth = np.full((h, w), z)
    V = vertex_map(depth, K)
    geom = np.where(np.arange(w)[None, :] < w // 2, 1, 2).repeat(h, axis=0)
    return DepthFrame(K, depth, V, normal_map(V), V.copy(), geom, np.eye(3), np.zeros(3))


def test_pairs_with_their_own_pixel_are_true_and_every_point_has_a_partner():
    f = wall_frame()
    ok = np.flatnonzero(f.valid.reshape(-1))
    pts, geom = f.true_points.reshape(-1, 3)[ok], f.geom.reshape(-1)[ok]
    s = score_correspondences(pts, geom, f, np.arange(len(ok)), ok, tol=0.01)
    assert s.precision == 1.0 and s.recall == 1.0 and s.partners == len(ok)


def test_a_pair_across_geoms_or_beyond_tol_is_false():
    f = wall_frame()
    ok = np.flatnonzero(f.valid.reshape(-1))
    pts, geom = f.true_points.reshape(-1, 3)[ok], f.geom.reshape(-1)[ok]
    wrong_geom = geom.copy()
    wrong_geom[:] = 7
    assert score_correspondences(pts, wrong_geom, f, np.arange(len(ok)), ok, 0.01).precision == 0.0
    shifted = np.roll(ok, 3)   # each point paired with a pixel 3 columns away: ~4 cm at 2 m
    s = score_correspondences(pts, geom, f, np.arange(len(ok)), shifted, tol=0.01)
    assert s.precision == 0.0 and s.recall == 0.0


def test_hidden_or_unmeasured_points_have_no_partner():
    f = wall_frame()
    behind = np.array([[0.0, 0.0, 3.0]])          # behind the wall: its pixel sees the wall at 2 m
    outside = np.array([[5.0, 0.0, 2.0]])         # outside the view
    assert not has_partner(np.vstack([behind, outside]), np.array([1, 1]), f, 0.03).any()
    f.depth[:] = np.nan                            # nothing measured: no partner either
    f.normals[:] = np.nan
    assert not has_partner(f.true_points.reshape(-1, 3)[:5], np.ones(5, int), f, 0.03).any()


def test_no_pairs_gives_nan_precision_not_one():
    f = wall_frame()
    ok = np.flatnonzero(f.valid.reshape(-1))[:10]   # ten points the frame sees: partners exist
    s = score_correspondences(f.true_points.reshape(-1, 3)[ok], f.geom.reshape(-1)[ok], f,
                              np.zeros(0, np.int64), np.zeros(0, np.int64), 0.03)
    assert np.isnan(s.precision) and s.recall == 0.0


def test_relative_pose_error_ignores_earlier_drift():
    from scipy.spatial.transform import Rotation
    R0, t0 = np.eye(3), np.zeros(3)
    R1, t1 = Rotation.from_euler("z", 5, degrees=True).as_matrix(), np.array([0.1, 0, 0])
    drift = Rotation.from_euler("x", 20, degrees=True).as_matrix()
    off = np.array([1.0, 2.0, 3.0])   # both estimates moved by one rigid transform: the step is exact
    trans, rot = relative_pose_error(R0, t0, R1, t1, drift @ R0, drift @ t0 + off, drift @ R1, drift @ t1 + off)
    assert trans == pytest.approx(0, abs=1e-12) and rot == pytest.approx(0, abs=1e-6)
    trans, rot = relative_pose_error(R0, t0, R1, t1, R0, t0, R1, t1 + np.array([0, 0.002, 0]))
    assert trans == pytest.approx(0.002, abs=1e-12) and rot == pytest.approx(0, abs=1e-6)


def test_wrong_poses_and_lost_frames_are_counted_results_not_untrusted_runs():
    """A step accepted by ICP but more than WRONG_STEP_MM off the true step is a silent failure,
    counted in ``wrong_steps``; a large step error right after a failed (held) frame is not counted.
    Neither makes the run untrusted (the method failed at its job; the harness measured it): only a
    run with no correspondence at all is."""
    import pandas as pd

    from assocbench.tracks.dense.summary import WRONG_STEP_MM, dense_status, wrong_accepted
    frames = pd.DataFrame({"frame": [0, 1, 2, 3], "icp_failed": [0, 0, 0, 0], "pairs": [0, 9, 9, 9],
                           "step_error_mm": [np.nan, 1.0, 2 * WRONG_STEP_MM, 2.0]})
    assert wrong_accepted(frames) == 1 and dense_status(frames) == "ok"
    frames["step_error_mm"] = [np.nan, 1.0, 0.5 * WRONG_STEP_MM, 2.0]
    assert wrong_accepted(frames) == 0 and dense_status(frames) == "ok"
    frames["icp_failed"], frames["step_error_mm"] = [0, 1, 0, 0], [np.nan, 80.0, 2 * WRONG_STEP_MM, 2.0]
    assert wrong_accepted(frames) == 0 and dense_status(frames) == "ok"
    frames["pairs"] = [0, 0, 0, 0]
    assert dense_status(frames) == "no correspondences in any frame"


def test_a_frame_whose_method_raised_is_a_failure_not_an_icp_failure():
    """The run holds the pose of a frame whose method raised as it holds a lost frame's, but the
    two are told apart: ICP losing track is a counted result, the method's code failing makes the
    run not ok."""
    import pandas as pd

    from assocbench.tracks.dense.summary import METHOD_FAILED, dense_status, icp_failures
    frames = pd.DataFrame({"frame": [0, 1, 2, 3], "icp_failed": [False, True, True, False], "pairs": [0, 9, 0, 9],
                           "icp_reason": ["first frame", "lost direction", METHOD_FAILED, "converged"],
                           "error": ["", "", "ValueError: boom", ""]})
    assert icp_failures(frames) == 1 and dense_status(frames) == "1/3 frames failed"
    frames["error"] = ""
    assert icp_failures(frames) == 2 and dense_status(frames) == "ok"


def test_icp_ms_leaves_out_the_frames_whose_method_call_failed():
    """A method that raises at once (or hangs until killed) spends no ICP time worth a median: such a
    run's ICP ms must not read fast (or slow) because of its failed calls."""
    import pandas as pd

    from assocbench.tracks.dense.summary import METHOD_FAILED, summarize_dense
    n = 6
    pose = {f"{p}{c}": 0.0 for p in ("true_", "est_") for c in ("x", "y", "z", "qx", "qy", "qz")}
    frames = pd.DataFrame({"frame": range(n), "icp_failed": [False, False, True, True, True, False],
                           "icp_reason": ["first frame", "converged", METHOD_FAILED, METHOD_FAILED, METHOD_FAILED,
                                          "converged"],
                           "error": ["", "", "ValueError: boom", "ValueError: boom", "ValueError: boom", ""],
                           "icp_s": [np.nan, 0.012, 1e-5, 1e-5, 1e-5, 0.014], "fusion_s": 0.01, "map_points": 100,
                           **pose, "true_qw": 1.0, "est_qw": 1.0})
    row = summarize_dense(frames)
    assert row["icp_ms"] == pytest.approx(13.0) and row["failures"] == 3 and row["icp_failures"] == 0



@pytest.mark.parametrize("fails", [[2, 3, 4], [1, 2, 3, 4, 5]])
def test_fps_leaves_out_the_frames_whose_method_call_failed(fails):
    """Throughput, like ICP ms, counts only the frames whose method call did not fail: a method that
    raised at once on every frame read 307.8 frames/s against the projective method's 36.8 (the cold
    check found), one that hung until killed read slow; none left: NaN (shown as n/a), not a rate."""
    import pandas as pd

    from assocbench.tracks.dense.summary import METHOD_FAILED, summarize_dense
    n = 6
    failed = np.isin(np.arange(n), fails)
    pose = {f"{p}{c}": 0.0 for p in ("true_", "est_") for c in ("x", "y", "z", "qx", "qy", "qz")}
    frames = pd.DataFrame({"frame": range(n), "icp_failed": failed,
                           "icp_reason": np.where(failed, METHOD_FAILED, "converged"),
                           "error": np.where(failed, "ValueError: boom", ""),
                           "icp_s": np.where(failed, 1e-5, 0.012), "predict_s": 0.002,
                           "fusion_s": np.where(failed, np.nan, 0.01), "map_points": 100,
                           **pose, "true_qw": 1.0, "est_qw": 1.0})
    frames.loc[0, ["icp_s", "predict_s"]] = np.nan     # frame 0: given pose, fused only
    row = summarize_dense(frames)
    if len(fails) == n - 1:
        assert np.isnan(row["fps"]) and np.isnan(row["icp_ms"]) and row["status"] != "ok"
    else:
        assert row["fps"] == pytest.approx(3 / (0.01 + 2 * (0.002 + 0.012 + 0.01)))

def test_compiled_truth_equals_its_numpy_definition():
    """``true_pairs`` and ``has_partner`` (compiled) against the definitions written in numpy, on a
    frame of two geoms with noisy source truth, NaN truth and points outside the view."""
    f = wall_frame(w=64, h=48)
    rng = np.random.default_rng(4)
    n = 3000
    pix = rng.integers(0, 64 * 48, n)
    src = f.true_points.reshape(-1, 3)[pix] + rng.normal(0, 0.02, (n, 3))
    src[::50] = np.nan
    src[1::70] += [9.0, 0.0, 0.0]
    geom = f.geom.reshape(-1)[pix].copy()
    geom[::7] = 3 - geom[::7]
    q, g = f.true_points.reshape(-1, 3), f.geom.reshape(-1)
    source = rng.integers(0, n, 2 * n)
    pixel = rng.integers(0, 64 * 48, 2 * n)
    pixel[::2] = pix[source[::2]]
    want = (g[pixel] == geom[source]) & (np.linalg.norm(q[pixel] - src[source], axis=1) < 0.03)
    from assocbench.tracks.dense.metrics import true_pairs
    np.testing.assert_array_equal(true_pairs(src, geom, f, source, pixel, 0.03), want)
    assert 0 < want.sum() < len(want)
    K = f.K
    with np.errstate(invalid="ignore", divide="ignore"):
        u, v = np.rint(K.f * src[:, 0] / src[:, 2] + K.cx), np.rint(K.f * src[:, 1] / src[:, 2] + K.cy)
        inside = (src[:, 2] > 0) & (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    j = np.where(inside, np.nan_to_num(v) * K.width + np.nan_to_num(u), 0).astype(int)
    partner = inside & f.valid.reshape(-1)[j] & (g[j] == geom) & (np.linalg.norm(q[j] - src, axis=1) < 0.03)
    np.testing.assert_array_equal(has_partner(src, geom, f, 0.03), partner)
    assert 0 < partner.sum() < n
