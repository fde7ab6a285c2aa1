"""The appearance baseline: Lowe's ratio test inside the Mahalanobis gate, one-to-one; and every
geometric method ignores descriptors."""

from __future__ import annotations

import numpy as np
import pytest
from problems import random_problem

from assocbench import Problem, make_associator
from assocbench.associators.registry import geometric_builtins

GEOMETRIC = sorted(geometric_builtins())


def row(*values: float) -> list[float]:
    return [float(v) for v in values]


def problem(z, zhat, descriptors, landmark_descriptors, sigma: float = 2.0) -> Problem:
    z, zhat = np.array(z, float), np.array(zhat, float)
    return Problem(z, np.repeat(np.eye(2)[None], len(z), 0), zhat, sigma**2 * np.eye(2 * len(zhat)), volume=1e4,
                   descriptors=np.array(descriptors, float), landmark_descriptors=np.array(landmark_descriptors, float))


def test_inside_the_gate_the_descriptor_chooses_not_the_distance():
    """Landmark at (0, 0); a keypoint 1 px away that looks wrong, one 4 px away that looks right."""
    p = problem([[1, 0], [4, 0], [200, 200]], [[0, 0]], [row(9, 0), row(0, 1), row(5, 5)], [row(0, 1.1)])
    assert make_associator("appearance").associate(p).tolist() == [1]
    assert make_associator("mnn").associate(p).tolist() == [0]


def test_a_match_no_better_than_the_images_next_best_is_refused():
    """The gated keypoint is at distance 1 from the landmark's descriptor; a keypoint far outside the
    gate is at 1.2: the ratio 0.83 fails Lowe's 0.8, passes 0.9."""
    p = problem([[1, 0], [300, 300]], [[0, 0]], [row(1, 0), row(1.2, 0)], [row(0, 0)])
    assert make_associator("appearance").associate(p).tolist() == [-1]
    assert make_associator("appearance", ratio=0.9).associate(p).tolist() == [0]


def test_keypoints_at_one_position_count_once_in_the_ratio_test():
    """Two orientations of one keypoint (same position, near descriptors) do not make it ambiguous."""
    p = problem([[1, 0], [1, 0], [300, 300]], [[0, 0]], [row(1, 0), row(1.05, 0), row(10, 0)], [row(0, 0)])
    assert make_associator("appearance").associate(p).tolist() == [0]


def test_nothing_outside_the_gate_is_paired_and_each_keypoint_once():
    p = problem([[1, 0], [60, 0]], [[0, 0], [1.5, 0.5], [40, 40]], [row(0, 0), row(3, 3)],
                [row(0, 0.1), row(0, 0.2), row(3, 3)])
    # landmark 2 looks like keypoint 1 but it lies 28 px away, far outside its 3 sigma gate
    assert make_associator("appearance").associate(p).tolist() == [0, -1, -1]


def test_a_problem_without_descriptors_is_refused():
    p = random_problem(np.random.default_rng(0), n=3, m=3)
    with pytest.raises(ValueError, match="appearance needs Problem.descriptors"):
        make_associator("appearance").associate(p)


@pytest.mark.parametrize("method", GEOMETRIC)
def test_geometric_methods_ignore_descriptors(method, rng):
    from assocbench.models.synthetic import range_bearing_problem

    for seed in range(3):
        plain, _ = range_bearing_problem(np.random.default_rng(seed), n=12)
        given = Problem(plain.z, plain.R, plain.zhat, plain.P, plain.landmark_ids, plain.volume, plain.angular,
                        descriptors=rng.normal(size=(plain.m, 8)), landmark_descriptors=rng.normal(size=(plain.n, 8)))
        assert make_associator(method).associate(given).tolist() == make_associator(method).associate(plain).tolist()
