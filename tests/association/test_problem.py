"""Problem and association validation: bad input names the field."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench import Problem, validate_association


def make(**over):
    fields = dict(z=np.zeros((2, 2)), R=np.repeat(np.eye(2)[None], 2, 0), zhat=np.ones((3, 2)), P=np.eye(6), volume=100.0)
    fields.update(over)
    return Problem(**fields)


@pytest.mark.parametrize("over,field", [
    (dict(P=-np.eye(6)), "Problem.P"),
    (dict(P=np.triu(np.ones((6, 6)))), "Problem.P"),
    (dict(R=np.stack([np.eye(2), -np.eye(2)])), r"Problem.R\[1\]"),
    (dict(z=np.array([[np.nan, 0.0], [0.0, 0.0]])), "Problem.z"),
    (dict(zhat=np.ones((3, 3))), "Problem"),
    (dict(P=np.eye(5)), "Problem.P"),
    (dict(R=np.eye(2)), "Problem.R"),
    (dict(z=np.zeros(4)), "Problem.z"),
    (dict(volume=0.0), "Problem.volume"),
    (dict(angular=(2,)), "Problem.angular"),
    (dict(landmark_ids=np.arange(2)), "Problem.landmark_ids"),
])
def test_bad_problem_raises_value_error_naming_the_field(over, field):
    with pytest.raises(ValueError, match=field):
        make(**over)


def test_empty_problems_are_valid():
    p = Problem(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2)), np.zeros((0, 0)))
    assert (p.m, p.n, p.d) == (0, 0, 2)


@pytest.mark.parametrize("assoc,msg", [
    ([0, 0, -1], "more than once"), ([0, 5, -1], "outside"), ([0, -2, 1], "outside"),
    ([0, 1], "shape"), ([0.5, -1, -1], "integer"),
])
def test_invalid_associations_are_rejected(assoc, msg):
    with pytest.raises(ValueError, match=msg):
        validate_association(np.array(assoc), make())


def test_valid_association_passes():
    assert validate_association([1, -1, 0], make()).tolist() == [1, -1, 0]
