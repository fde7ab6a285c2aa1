"""The harness checks each frame's whole P (``Problem.validate``) and its truth
(``FrameTruth.validate``) before any method sees it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from assocbench import Problem
from assocbench.association.truth import FrameTruth
from assocbench.errors import UserError
from assocbench.harness import runner


def test_a_frames_problem_is_refused_when_its_cross_terms_are_wrong():
    """Construction accepts a P whose diagonal blocks are sound (it reads only those); the open
    loop's problems are checked whole before any method runs or is scored."""
    P = np.kron(np.ones((3, 3)), np.array([[2.0, 0.5], [0.5, 1.0]])) - 1e-6 * np.eye(6)
    bad = Problem(np.zeros((2, 2)), np.repeat(np.eye(2)[None], 2, 0), np.ones((3, 2)), P)
    track = SimpleNamespace(name="planar", problem=lambda source, k, run: (bad, None))
    with pytest.raises(UserError, match="^the planar track's frame 0 is invalid: Problem.P is not positive semidefinite"):
        runner.Problems(track, [0], None)[0]


def impossible_truth(n: int, m: int) -> FrameTruth:
    """Every landmark's true feature is feature 0: what a plugin track's bug made."""
    return FrameTruth(np.zeros(m, np.int64), np.zeros(n, np.int64), np.ones(n, bool))


def test_a_frames_problem_refuses_an_impossible_truth_naming_the_track_and_frame():
    """Reproduction: a plugin track whose ``problems()`` says every landmark's true feature is 0
    was scored as ok (recall 0.8833); the truth was never checked against its problem."""
    good = Problem(np.zeros((4, 2)), np.repeat(np.eye(2)[None], 4, 0), np.ones((3, 2)), np.eye(6))
    fine = FrameTruth(np.array([0, 1, 2, -1]), np.array([0, 1, 2]), np.ones(3, bool))
    frames = [(good, fine), (good, impossible_truth(3, 4))]
    track = SimpleNamespace(name="toy", problem=lambda source, k, run: frames[k])
    problems = runner.Problems(track, [0, 1], None)
    assert problems[0][1] is fine
    with pytest.raises(UserError, match="^the toy track's frame 1 is invalid: FrameTruth.association pairs feature 0"):
        problems[1]


def test_a_run_on_a_track_with_an_impossible_truth_stops_in_one_line(tmp_path):
    """Reproduction: ``TOY_BAD_TRUTH=1 assocbench run --scene toy.xml`` (the toy plugin track, every
    landmark's true feature 0) printed an ok summary and exited 0."""
    from tests.tracks.test_toy_track import SCENE, cli

    scene = tmp_path / "toy.xml"
    scene.write_text(SCENE)
    done = cli("run", "--method", "mnn", "--scene", str(scene), "--frames", "3", "--out", str(tmp_path / "run"),
               TOY_BAD_TRUTH="1")
    assert done.returncode == 2, done.stderr
    last = done.stderr.splitlines()[-1]   # earlier lines: a note that kernels compile, on a cold cache
    assert last.startswith("assocbench: error: the toy track's frame 0 is invalid: FrameTruth.association"), last
    assert "Traceback" not in done.stderr and not (tmp_path / "run").exists()


def test_the_closed_loop_refuses_an_impossible_truth(monkeypatch, room_sequence):
    """The closed loop makes its truth from the track's labels (``loop_truth``); it is checked the
    same way before the method sees the frame."""
    from runs import run_on

    from assocbench.harness import loop

    monkeypatch.setattr(loop, "loop_truth", lambda ids, truth, labels, visible: impossible_truth(len(ids), len(labels)))
    with pytest.raises(UserError, match="^the camera track's frame 0 is invalid: FrameTruth.association pairs feature 0"):
        list(loop.loop_records(*run_on(room_sequence, "mnn")))
