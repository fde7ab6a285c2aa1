"""``belief.planar.open_loop_pose`` is the pose the planar and lines problems were predicted from
(the pictures draw the scan there): their predictions are reproduced from it."""

from __future__ import annotations

import numpy as np
from line_synth_seq import line_seq

from assocbench.belief.config import BeliefConfig
from assocbench.belief.planar import open_loop_pose
from assocbench.models import polar_line, range_bearing
from assocbench.tracks.lines.belief import make_line_problem
from assocbench.tracks.planar.sequence import PlanarSequenceSpec, make_planar_sequence
from assocbench.tracks.plane_belief import make_planar_problem


def test_the_lines_problem_is_predicted_from_the_open_loop_pose():
    seq = line_seq(steps=6)
    cfg = BeliefConfig(sigma_position=0.2, sigma_rotation=3.0, clutter=2)
    for k in (0, len(seq) - 1):
        problem, _ = make_line_problem(seq, k, cfg, seed=7)
        pose = open_loop_pose(seq.poses[k], cfg, 7, k)
        assert not np.allclose(pose, seq.poses[k])
        np.testing.assert_allclose(polar_line.predict(pose, seq.lines[problem.landmark_ids]), problem.zhat)


def test_the_planar_problem_is_predicted_from_the_open_loop_pose():
    seq = make_planar_sequence(PlanarSequenceSpec(scene="post_grid", frames=3))
    cfg = BeliefConfig(sigma_position=0.2, sigma_rotation=3.0, sigma_landmark=0.0, sigma_common=0.0, clutter=2)
    problem, _ = make_planar_problem(seq, 1, cfg, seed=3)
    pose = open_loop_pose(seq.poses[1], cfg, 3, 1)
    np.testing.assert_allclose(range_bearing.predict(pose, seq.posts[problem.landmark_ids]), problem.zhat)
