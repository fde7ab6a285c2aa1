"""The photos track: Balbianello's frames as association problems scored against the reference, its
runs from the command line, and its refusals (no gtsam, a sixth image, another reconstruction)."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pandas as pd
import pytest
from cli_errors import assert_one_line_error

from assocbench.association.compatibility import pairwise_nis
from assocbench.cli.main import main
from assocbench.harness.config import load_run_config, run_spec

pytestmark = pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the photos track reads gtsam's data")


def spec(*sets: str, seed: int = 0, method: str = "mnn"):
    return run_spec(load_run_config(None, list(sets), track="photos", method=method, seed=seed))


def test_a_frame_is_every_keypoint_against_the_landmarks_of_the_other_images():
    run = spec()
    source = run.source
    assert len(source) == 5 and source.name == "balbianello"
    rec = source.recording()
    for k in range(5):
        problem, truth = run.track_impl.problem(source, k, run)
        photo = rec.photos[k]
        assert problem.m == len(photo.keys) and problem.descriptors.shape == (problem.m, 128)
        assert problem.landmark_descriptors.shape == (problem.n, 128) and 380 <= problem.n <= 430
        assert problem.volume == 640 * 427
        ids = problem.landmark_ids
        assert np.all(source[k].in_map[ids])          # seen with a keypoint in another image
        inside = (problem.zhat >= -0.5) & (problem.zhat <= [639.5, 426.5])
        assert inside.all()
        labelled = truth.feature_labels[truth.feature_labels >= 0]
        assert np.all(source[k].in_map[labelled])     # a landmark outside this frame's map labels nothing
        j = np.flatnonzero(truth.association >= 0)
        assert np.array_equal(truth.feature_labels[truth.association[j]], ids[j])
        assert np.array_equal(truth.visible, photo.seen[ids])


def test_the_reference_pairs_are_consistent_with_the_reported_covariance():
    """At the default belief (σ 0.005 units, 0.1°, landmarks 0.002, keypoints 0.5 px) the reference
    pairs' mean NIS is the measurement's dimension: measured 2.02 over 6 seeds x 5 images."""
    nis = []
    for seed in range(6):
        run = spec(seed=seed)
        for k in range(5):
            problem, truth = run.track_impl.problem(run.source, k, run)
            j = np.flatnonzero(truth.association >= 0)
            nis.extend(pairwise_nis(problem)[0][truth.association[j], j])
    assert len(nis) > 5000
    assert np.mean(nis) == pytest.approx(2.0, rel=0.05)


def test_the_same_seed_gives_the_same_problem_and_another_seed_another():
    a, b, c = spec(seed=3), spec(seed=3), spec(seed=4)
    first = a.track_impl.problem(a.source, 2, a)[0]
    assert first == b.track_impl.problem(b.source, 2, b)[0]
    assert not np.array_equal(first.zhat, c.track_impl.problem(c.source, 2, c)[0].zhat)


def test_a_run_from_the_command_line_is_scored_against_the_reference(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--track", "photos", "--method", "mnn", "--frames", "2", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "mnn on balbianello (photos track): open loop, 2 frames, seed 0, scored against the reference" in printed
    summary = pd.read_csv(out / "summary.csv").iloc[0]
    assert summary["status"] == "ok" and summary["frames"] == 2 and summary["recall"] > 0.5


@pytest.mark.parametrize("args,message", [
    (["--frames", "6"], "frames 6: balbianello has 5 images, one frame each"),
    (["--scene", "victoria_park"], "the photos track reads the reconstruction 'balbianello', not 'victoria_park'"),
    (["--set", "belief.clutter=3"], "belief.clutter"),
    (["--set", "photos.match_radius=0"], "photos.match_radius"),
    (["--set", "belief.sigma_pixel=1e-300"], "belief.sigma_pixel must be a finite number in [1e-06, 10000.0]"),
    (["--set", "belief.sigma_pixel=1e300"], "belief.sigma_pixel must be a finite number in [1e-06, 10000.0]"),
    (["--set", "belief.sigma_position=1e300"], "belief.sigma_position must be a finite number in [0, 1000.0]"),
    (["--set", "belief.sigma_landmark=1e300"], "belief.sigma_landmark must be a finite number in [0, 1000.0]"),
])
def test_bad_runs_are_refused_in_one_line(capsys, args, message):
    """Reproduction of the belief cases: `assocbench run --scene balbianello --set
    belief.sigma_pixel=1e-300` (R = σ²I is 0, not positive definite), `sigma_position=1e300` or
    `sigma_landmark=1e300` (σ² overflows: OverflowError) crashed the worker with a traceback, exit 1:
    the photos belief had no upper bound and sigma_pixel no lower one, unlike the other tracks'."""
    assert_one_line_error(capsys, main(["run", "--track", "photos", "--method", "mnn", *args]), message)


@pytest.mark.parametrize("setting", ["belief.sigma_pixel=1e-6", "belief.sigma_pixel=1e4", "belief.sigma_position=1000",
                                     "belief.sigma_landmark=1000", "belief.sigma_common=1000",
                                     "belief.miscalibration=1000"])
def test_the_photos_belief_computes_at_the_ends_of_its_ranges(tmp_path, capsys, setting):
    """At each bound the run is measured: ok, or not ok with its reason, never a crash."""
    code = main(["run", "--track", "photos", "--method", "mnn", "--frames", "2", "--set", setting,
                 "--out", str(tmp_path), "--format", "csv"])
    err = capsys.readouterr().err
    assert code in (0, 1) and "Traceback" not in err and "error:" not in err, err
    assert (tmp_path / "summary.csv").is_file()


def test_without_gtsam_the_track_is_listed_unavailable_and_a_run_is_refused_naming_the_extra(capsys, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "gtsam" else real(name, *a))
    assert main(["list", "tracks"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("photos"))
    assert "unavailable here: gtsam is not installed (pip install 'assocbench[gtsam]'" in line
    assert_one_line_error(capsys, main(["run", "--track", "photos", "--method", "jcbb"]),
                          "the photos track is unavailable here: gtsam is not installed", "assocbench[gtsam]")


def test_the_leaderboard_card_says_the_runs_are_scored_against_the_reference():
    from assocbench.harness.leaderboard import card
    from assocbench.tracks.registry import get_track

    photos = card(get_track("photos"), False)
    assert photos["scored_against"] == "reference" and card(get_track("camera"), False)["scored_against"] == "truth"
    assert json.loads(json.dumps(photos)) == photos
