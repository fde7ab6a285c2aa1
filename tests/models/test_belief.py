"""Belief model of the camera track: Jacobians and consistency of the reported covariance."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.association.compatibility import pairwise_nis
from assocbench.belief.config import BeliefConfig, map_mask
from assocbench.models.camera import Intrinsics, look_at
from assocbench.models.pinhole import perturb_pose, predict_bundle
from assocbench.tracks.camera.belief import make_problem
from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence
from assocbench.tracks.camera.settings import DetectorConfig


def test_analytic_jacobians_match_central_differences(rng):
    K = Intrinsics.from_fovy(640, 480, 60.0)
    p = np.array([0.3, -0.2, 1.4])
    R = look_at(p, np.array([3.0, 1.0, 1.6]))
    landmarks = np.array([3.0, 1.0, 1.6]) + rng.normal(0, 0.8, (6, 3))
    h, J_pose, J_l, _ = predict_bundle(R, p, landmarks, K)
    eps = 1e-6
    for k in range(6):
        step = np.zeros(6)
        step[k] = eps
        Rp, pp = perturb_pose(R, p, step[:3], step[3:])
        Rm, pm = perturb_pose(R, p, -step[:3], -step[3:])
        num = (predict_bundle(Rp, pp, landmarks, K)[0] - predict_bundle(Rm, pm, landmarks, K)[0]) / (2 * eps)
        assert np.abs(num - J_pose[:, :, k]).max() <= 1e-6 * np.abs(J_pose).max()
    for k in range(3):
        step = np.zeros(3)
        step[k] = eps
        num = (predict_bundle(R, p, landmarks + step, K)[0] - predict_bundle(R, p, landmarks - step, K)[0]) / (2 * eps)
        assert np.abs(num - J_l[:, :, k]).max() <= 1e-6 * np.abs(J_l).max()


def test_mean_nis_of_true_features_is_d_within_5_percent():
    """Detected features carry 1 px of added noise, as the belief reports."""
    seq = load_sequence(SequenceSpec(scene="room", frames=12, detector=DetectorConfig(noise_px=1.0)))
    cfg = BeliefConfig(sigma_position=0.05, sigma_rotation=1.0, sigma_landmark=0.02, sigma_pixel=1.0)
    nis = []
    for seed in range(20):
        for k in range(len(seq)):
            problem, truth = make_problem(seq, k, cfg, seed)
            j = np.flatnonzero(truth.association >= 0)
            nis.extend(pairwise_nis(problem)[0][truth.association[j], j])
    assert len(nis) >= 2000
    assert np.mean(nis) == pytest.approx(2.0, rel=0.05)


def test_miscalibration_inflates_nis(room_sequence):
    def mean_nis(k):
        cfg = BeliefConfig(sigma_position=0.05, sigma_rotation=1.0, miscalibration=k)
        vals = []
        for f in range(0, len(room_sequence), 3):
            problem, truth = make_problem(room_sequence, f, cfg, 1)
            j = np.flatnonzero(truth.association >= 0)
            vals.extend(pairwise_nis(problem)[0][truth.association[j], j])
        return np.mean(vals)

    assert mean_nis(2.0) > 2.5 * mean_nis(1.0)


def test_problem_truth_and_map_fraction(room_sequence):
    problem, truth = make_problem(room_sequence, 3, BeliefConfig(map_fraction=0.5, clutter=7), 0)
    assert problem.m == len(room_sequence.features[3]) + 7
    assert np.all(truth.feature_labels[-7:] == -1)
    in_map = map_mask(len(room_sequence.landmarks), BeliefConfig(map_fraction=0.5), 0)
    assert in_map.sum() == round(0.5 * len(in_map))
    assert in_map[problem.landmark_ids].all()
    labelled = truth.feature_labels[truth.feature_labels >= 0]
    assert len(labelled) and in_map[labelled].all()
    assert (room_sequence.labels[3] >= 0).sum() > len(labelled)  # unmapped landmarks' features became clutter
    for j, i in enumerate(truth.association):
        if i >= 0:
            assert truth.feature_labels[i] == problem.landmark_ids[j]
