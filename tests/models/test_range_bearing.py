"""The planar track's range-bearing model: values, Jacobians against central differences, the
inverse, and the wrap of the bearing across ±π."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.models.range_bearing import inverse, inverse_jacobians, jacobians, pose_error, predict, wrap

RNG = np.random.default_rng(7)
POSES = [np.array([0.3, -1.2, 0.4]), np.array([2.0, 1.0, np.pi - 0.01]), np.array([-1.0, 0.5, -3.1])]
LANDMARKS = np.array([[4.0, 1.0], [-2.0, 3.5], [0.0, -4.0], [-3.0, 0.48]])


def _numeric(f, x, eps=1e-6):
    cols = []
    for i in range(len(x)):
        dx = np.zeros(len(x))
        dx[i] = eps
        diff = f(x + dx) - f(x - dx)
        diff[..., 1] = wrap(diff[..., 1])   # the bearing may cross ±π between the two points
        cols.append(diff / (2 * eps))
    return np.stack(cols, axis=-1)


def test_values_on_a_known_geometry():
    z = predict(np.array([1.0, 1.0, np.pi / 2]), np.array([[1.0, 3.0], [0.0, 1.0]]))
    np.testing.assert_allclose(z, [[2.0, 0.0], [1.0, np.pi / 2]], atol=1e-15)


@pytest.mark.parametrize("pose", POSES)
def test_jacobians_match_central_differences(pose):
    H_pose, H_l = jacobians(pose, LANDMARKS)
    np.testing.assert_allclose(H_pose, _numeric(lambda x: predict(x, LANDMARKS), pose), atol=1e-7)
    for j, lm in enumerate(LANDMARKS):
        np.testing.assert_allclose(H_l[j], _numeric(lambda l: predict(pose, l[None])[0], lm), atol=1e-7)


@pytest.mark.parametrize("pose", POSES)
def test_inverse_round_trips_and_its_jacobians(pose):
    for lm in LANDMARKS:
        z = predict(pose, lm[None])[0]
        np.testing.assert_allclose(inverse(pose, z), lm, atol=1e-12)
        G_pose, G_z = inverse_jacobians(pose, z)
        num_pose = np.stack([(inverse(pose + e, z) - inverse(pose - e, z)) / 2e-6 for e in 1e-6 * np.eye(3)], axis=1)
        num_z = np.stack([(inverse(pose, z + e) - inverse(pose, z - e)) / 2e-6 for e in 1e-6 * np.eye(2)], axis=1)
        np.testing.assert_allclose(G_pose, num_pose, atol=1e-7)
        np.testing.assert_allclose(G_z, num_z, atol=1e-7)


def test_bearing_wraps_behind_the_robot():
    """A landmark straight behind a robot heading ~0 is at a bearing of ±π, and one a hair either
    side of it differs by a hair, not by 2π."""
    pose = np.array([0.0, 0.0, 0.0])
    z = predict(pose, np.array([[-5.0, 1e-6], [-5.0, -1e-6]]))
    assert abs(abs(z[0, 1]) - np.pi) < 1e-6 and abs(abs(z[1, 1]) - np.pi) < 1e-6
    assert abs(wrap(z[0, 1] - z[1, 1])) < 1e-6
    assert abs(pose_error(np.array([0, 0, np.pi - 0.01]), np.array([0, 0, -np.pi + 0.01]))[2] + 0.02) < 1e-12


def test_a_landmark_on_the_robot_is_refused():
    with pytest.raises(ValueError, match="bearing is undefined"):
        jacobians(np.array([1.0, 2.0, 0.0]), np.array([[1.0, 2.0]]))
