"""The harness checks each frame's whole P (``Problem.validate``) before any method sees it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from assocbench import Problem
from assocbench.harness import runner


def test_a_frames_problem_is_refused_when_its_cross_terms_are_wrong():
    """Construction accepts a P whose diagonal blocks are sound (it reads only those); the open
    loop's problems are checked whole before any method runs or is scored."""
    P = np.kron(np.ones((3, 3)), np.array([[2.0, 0.5], [0.5, 1.0]])) - 1e-6 * np.eye(6)
    bad = Problem(np.zeros((2, 2)), np.repeat(np.eye(2)[None], 2, 0), np.ones((3, 2)), P)
    track = SimpleNamespace(problem=lambda source, k, run: (bad, None))
    with pytest.raises(ValueError, match="Problem.P is not positive semidefinite"):
        runner.Problems(track, [0], None)[0]
