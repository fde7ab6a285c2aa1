"""Per-frame scores (``scoring.metrics``): a frame the method failed on claims nothing of an answer."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from assocbench.association.truth import FrameTruth
from assocbench.harness.runner import failed_record
from assocbench.scoring.aggregate import summarize
from assocbench.scoring.metrics import score_frame, unscored_frame
from tests.problems import random_problem


def frame():
    """3 candidates and 3 features, candidate j's true feature j."""
    problem = random_problem(np.random.default_rng(0), 3, 3)
    return problem, FrameTruth(np.arange(3), np.arange(3), np.ones(3, bool))


def test_a_failed_frame_counts_its_misses_but_claims_no_joint_compatibility_or_surprisal():
    problem, truth = frame()
    record = unscored_frame(problem, truth)
    assert (record["tp"], record["fp"], record["fn"], record["perfect"]) == (0, 0, 3, False)
    assert math.isnan(record["jointly_compatible"]) and math.isnan(record["surprisal"])


def test_failed_frames_leave_the_summary_of_the_frames_that_answered_unchanged():
    problem, truth = frame()
    answered = [{"frame": k, **score_frame(problem, truth, np.arange(3)), "timed_out": False, "runtime_s": 0.001,
                 "proven_optimal": float("nan"), "true_mass": float("nan"), "error": ""} for k in range(2)]
    failed = failed_record(2, problem, truth, "RuntimeError: boom", 0.001)
    with_failure, without = summarize(pd.DataFrame(answered + [failed])), summarize(pd.DataFrame(answered))
    assert with_failure["jc_share"] == without["jc_share"]
    assert with_failure["surprisal_gap"] == without["surprisal_gap"]
    assert with_failure["recall"] < without["recall"] and with_failure["failures"] == 1
