"""RJC (randomised joint compatibility): jointly compatible output, reproducible for a seed, equal
to JCBB when the sample is every feature, clear parameter errors; and the gate-box shortcut of
``individually_compatible`` it relies on."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from problems import random_problem

from assocbench import UserError, make_associator, validate_association
from assocbench.association.compatibility import (
    chi2_threshold,
    individually_compatible,
    joint_nis,
    jointly_compatible,
    pairwise_nis,
)
from assocbench.associators.rjc import ransac_iterations
from assocbench.models.synthetic import lattice_problem, range_bearing_problem
from assocbench.tracks.camera.synthetic import camera_problem

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the repository


def some_problems():
    """Random problems (some with a wrapping dim) and range-bearing ones, small to medium."""
    rng = np.random.default_rng(7)
    for s in range(25):
        yield random_problem(rng, n=int(rng.integers(1, 9)), m=int(rng.integers(1, 10)), angular=(1,) if s % 3 else ())
    for s, n in enumerate([5, 10, 20, 40, 60]):
        yield range_bearing_problem(np.random.default_rng(s), n=n)[0]
        yield range_bearing_problem(np.random.default_rng(s), n=n, sigma_pose=(1.0, np.deg2rad(8.0)), extent=10.0)[0]


@pytest.mark.parametrize("params", [{}, {"sample_size": 1}, {"sample_size": 2, "iterations": 7}])
def test_output_is_valid_and_jointly_compatible(params):
    rjc = make_associator("rjc", **params)
    for p in some_problems():
        out = rjc.associate(p)
        validate_association(out, p)
        assert jointly_compatible(p, out, rjc.confidence)
        assert np.all(individually_compatible(p)[out[out >= 0], np.flatnonzero(out >= 0)])


def test_same_seed_same_answer_whatever_was_asked_before():
    problems = list(some_problems())
    first = make_associator("rjc", seed=3)
    answers = [first.associate(p) for p in problems]
    again = [first.associate(p) for p in reversed(problems)][::-1]   # another call history
    fresh = make_associator("rjc", seed=3)
    for p, a, b in zip(problems, answers, again):
        assert np.array_equal(a, b)
        assert np.array_equal(a, fresh.associate(p))


def test_other_seeds_are_each_valid():
    problems = [range_bearing_problem(np.random.default_rng(s), n=40, sigma_pose=(1.0, np.deg2rad(8.0)),
                                      extent=10.0)[0] for s in range(5)]
    for seed in range(6):
        rjc = make_associator("rjc", seed=seed)
        for p in problems:
            out = rjc.associate(p)
            validate_association(out, p)
            assert jointly_compatible(p, out)


def test_a_sample_of_every_feature_is_jcbb():
    """With at most ``sample_size`` gated features the one sample is the whole problem: the
    hypothesis is JCBB's, pairing for pairing, in one iteration."""
    jcbb = make_associator("jcbb")
    for p in some_problems():
        for rjc in (make_associator("rjc", sample_size=p.m), make_associator("rjc", sample_size=p.m, seed=9)):
            assert np.array_equal(rjc.associate(p), jcbb.associate(p))
            assert rjc.info["iterations"] == (1 if individually_compatible(p).any() else 0)
    rjc = make_associator("rjc")          # sample_size 4: problems with at most 4 features
    for p in some_problems():
        if p.m <= 4:
            assert np.sum(rjc.associate(p) >= 0) == np.sum(jcbb.associate(p) >= 0)


def test_ransac_count_is_the_papers():
    """t = ceil(log P_fail / log(1 - P_good^b)): 9 tries for P_fail 0.01, P_good 0.8 and b = 4."""
    assert ransac_iterations(0.01, 0.8, 4) == 9
    assert ransac_iterations(0.01, 0.8, 1) == 3
    assert ransac_iterations(0.01, 1.0, 4) == 1
    assert [ransac_iterations(0.01, 0.8, b) for b in range(1, 8)] == sorted(ransac_iterations(0.01, 0.8, b)
                                                                            for b in range(1, 8))


def test_adaptive_count_stops_once_every_feature_is_paired():
    """Every gated feature paired in the first iteration: P_good = 1, so one iteration."""
    n = 8
    zhat = np.column_stack([np.arange(n) * 40.0, np.zeros(n)])
    from assocbench import Problem

    p = Problem(zhat[::-1] + 0.3, np.repeat(np.eye(2)[None], n, 0), zhat, 4.0 * np.eye(2 * n), volume=1e5)
    rjc = make_associator("rjc")
    answer = rjc.associate(p)
    assert answer.tolist() == list(range(n))[::-1]
    assert rjc.info == {"iterations": 1, "required": 1, "nodes": rjc.info["nodes"], "timed_out": False,
                        "nis": pytest.approx(joint_nis(p, answer), rel=1e-12)}


def test_iteration_cap_is_reported_as_timed_out():
    p, _ = range_bearing_problem(np.random.default_rng(1), n=40)
    rjc = make_associator("rjc", sample_size=8, max_iterations=2)
    validate_association(rjc.associate(p), p)
    assert rjc.info["iterations"] == 2 and rjc.info["required"] > 2 and rjc.info["timed_out"] is True
    fixed = make_associator("rjc", iterations=5, max_iterations=2)   # a fixed count is not capped
    fixed.associate(p)
    assert fixed.info["iterations"] == 5 and fixed.info["timed_out"] is False


@pytest.mark.parametrize("params,needle", [
    ({"iterations": 0}, "params.iterations must be an integer >= 1, got 0"),
    ({"iterations": 2.5}, "params.iterations must be an integer >= 1, got 2.5"),
    ({"sample_size": 0}, "params.sample_size must be an integer >= 1, got 0"),
    ({"p_fail": 0.0}, "params.p_fail must be a finite number in (0, 1), got 0.0"),
    ({"p_good": 0.0}, "params.p_good must be a finite number in (0, 1], got 0.0"),
    ({"max_iterations": 0}, "params.max_iterations must be an integer >= 1, got 0"),
    ({"seed": -1}, "params.seed must be an integer >= 0, got -1"),
    ({"confidence": 1.0}, "params.confidence must be a finite number in (0, 1), got 1.0"),
])
def test_bad_parameters_are_one_line_errors(params, needle):
    with pytest.raises(UserError) as exc:
        make_associator("rjc", **params)
    assert str(exc.value) == needle


def test_bad_parameter_from_the_command_line_exits_2_with_one_line():
    proc = subprocess.run([sys.executable, "-m", "assocbench.cli.main", "run", "--method", "rjc", "--set",
                           "params.iterations=0"], capture_output=True, text=True, env={**os.environ, "PYTHONPATH": ROOT})
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "params.iterations must be an integer >= 1, got 0" in proc.stderr


def test_gate_box_gives_the_same_mask_as_every_nis():
    """``individually_compatible`` without NIS whitens only the pairs inside the gate's box; the
    mask must equal ``pairwise_nis <= χ²_d(c)`` exactly."""
    rng = np.random.default_rng(11)
    problems = [random_problem(rng, n=int(rng.integers(1, 9)), m=int(rng.integers(1, 9)), d=int(rng.integers(1, 4)),
                               angular=(0,) if s % 2 else ()) for s in range(60)]
    problems += [f(np.random.default_rng(s), n=60)[0] for s in range(4)
                 for f in (range_bearing_problem, camera_problem, lattice_problem)]
    for p in problems:
        nis = pairwise_nis(p)[0]
        for c in (0.5, 0.95, 0.99, 1 - 1e-9):
            assert np.array_equal(individually_compatible(p, c), nis <= chi2_threshold(p.d, c))


def test_sample_search_is_jcbb_with_the_other_rows_cleared():
    """The sample's JCBB runs on a sub-problem; it must be the search of the whole problem with
    the individual-compatibility rows of the unsampled features cleared: same pairings, same
    number of nodes."""
    from assocbench.association.compatibility import joint_gates, wrap_mask
    from assocbench.associators.anytime_search import anytime_jcbb
    from assocbench.associators.rjc import sample_hypothesis

    rng = np.random.default_rng(5)
    for p in some_problems():
        ic = individually_compatible(p)
        gate, wrap = joint_gates(p.d, p.n, 0.99), wrap_mask(p)
        for b in (1, 2, 4):
            sample = np.sort(rng.choice(p.m, size=min(b, p.m), replace=False))
            masked = np.zeros_like(ic)
            masked[sample] = ic[sample]
            feats, lms, info = anytime_jcbb((masked, p.P, p.z, p.zhat, p.R, wrap, gate), 10_000)
            nodes = info["nodes"]
            got_f, got_l, got_nodes, _ = sample_hypothesis(p, ic, sample, wrap, gate, 10_000)
            assert sorted(zip(got_l.tolist(), got_f.tolist())) == sorted(zip(lms.tolist(), feats.tolist()))
            assert got_nodes == nodes
