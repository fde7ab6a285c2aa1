"""The polar line model of the lines track: prediction, r ≥ 0 convention, Jacobians, inverse."""

import numpy as np
import pytest

from assocbench.models.polar_line import jacobians, line_from_points, predict, to_world
from assocbench.models.range_bearing import wrap


def test_prediction_matches_the_geometry_of_a_wall():
    # the wall x = 3 (α_w = 0, r_w = 3) from (1, 2) facing +y: 2 m ahead on the robot's right
    z = predict(np.array([1.0, 2.0, np.pi / 2]), np.array([[0.0, 3.0]]))[0]
    assert z == pytest.approx([-np.pi / 2, 2.0])


def test_robot_beyond_the_line_flips_to_r_positive():
    # the same wall from (5, 0), θ = 0: 2 m behind, so α = π (wrapped to −π) and r = 2
    z = predict(np.array([5.0, 0.0, 0.0]), np.array([[0.0, 3.0]]))[0]
    assert z[1] == pytest.approx(2.0)
    assert abs(wrap(z[0] - np.pi)) < 1e-12
    assert -np.pi <= z[0] < np.pi


@pytest.mark.parametrize("pose", [[1.0, 2.0, 0.3], [5.0, -1.0, -2.9], [0.2, 0.1, 3.1]])
def test_jacobians_match_central_differences(pose):
    pose = np.array(pose)
    lines = np.array([[0.0, 3.0], [np.pi / 2, 4.0], [2.5, 1.0], [-3.1, 2.0]])
    H_pose, H_line = jacobians(pose, lines)
    eps = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        diff = predict(pose + d, lines) - predict(pose - d, lines)
        diff[:, 0] = wrap(diff[:, 0])
        np.testing.assert_allclose(diff / (2 * eps), H_pose[:, :, k], atol=1e-7)
    for j in range(len(lines)):
        for k in range(2):
            d = np.zeros_like(lines)
            d[j, k] = eps
            diff = predict(pose, lines + d)[j] - predict(pose, lines - d)[j]
            diff[0] = wrap(diff[0])
            np.testing.assert_allclose(diff / (2 * eps), H_line[j, :, k], atol=1e-7)


def test_to_world_inverts_predict():
    pose = np.array([1.5, -0.7, 2.2])
    lines = np.array([[0.0, 3.0], [np.pi / 2, 4.0], [2.5, 1.0], [-3.1, 2.0]])
    back = to_world(pose, predict(pose, lines))
    np.testing.assert_allclose(wrap(back[:, 0] - lines[:, 0]), 0, atol=1e-12)
    np.testing.assert_allclose(back[:, 1], lines[:, 1], atol=1e-12)


def test_line_through_two_points():
    a, r = line_from_points([3.0, -1.0], [3.0, 5.0])
    assert (a, r) == pytest.approx((0.0, 3.0))
    a, r = line_from_points([-1.0, -2.0], [4.0, -2.0])   # y = −2: α = −π/2, r = 2
    assert (a, r) == pytest.approx((-np.pi / 2, 2.0))
    with pytest.raises(ValueError, match="two distinct points"):
        line_from_points([1.0, 1.0], [1.0, 1.0])
