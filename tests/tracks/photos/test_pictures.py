"""The photos track's pictures: a frame with its reference pairs, and a run's frame with its pairings
coloured against the reference (green where it agrees, red where not, orange where it left one out)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from assocbench.harness.config import load_run_config, run_spec
from assocbench.tracks.capabilities import RunFrame
from assocbench.viz import draw

pytestmark = pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the photos track reads gtsam's data")


def count(img: np.ndarray, color) -> int:
    return int(np.all(img == np.array(color, np.uint8), axis=2).sum())


@pytest.fixture(scope="module")
def run():
    return run_spec(load_run_config(None, [], track="photos", method="mnn"))


def test_the_frame_picture_draws_the_reference_pairs_at_twice_the_size(run):
    from assocbench.tracks.photos.pictures import frame_picture

    img, line = frame_picture(run, 1)
    assert img.shape == (854, 1280, 3) and img.dtype == np.uint8
    assert line.startswith("balbianello image 2: ") and "reference pairs" in line and "median 0.27 px" in line
    assert count(img, draw.YELLOW) > 500


def test_a_runs_picture_colours_each_pairing_against_the_reference(run):
    from assocbench.tracks.photos.pictures import run_pictures

    problem, truth = run.track_impl.problem(run.source, 0, run)
    right = truth.association.copy()
    wrong = right.copy()
    j = np.flatnonzero(right >= 0)[:20]
    wrong[j] = -1                                       # 20 reference pairs left out
    free = np.setdiff1d(np.arange(problem.m), right[right >= 0])
    k = np.flatnonzero(right < 0)[:10]
    wrong[k] = free[:10]                                # 10 candidates paired with keypoints the reference gives none
    record = {"tp": 0, "fp": 0, "fn": 0}
    none = np.full(problem.n, -1)
    frames = [RunFrame(0, problem, truth, a, "", record) for a in (right, wrong, none)]
    perfect, flawed, empty = list(run_pictures(run, run.source, frames))
    orange = (255, 140, 0)
    legend_red = count(empty, draw.RED)                # the key's sample: no pairing is drawn red
    assert count(perfect, draw.GREEN) > 500 and count(perfect, draw.RED) == legend_red
    assert count(empty, orange) > count(flawed, orange) > count(perfect, orange)
    assert count(flawed, draw.RED) > legend_red and count(flawed, draw.GREEN) < count(perfect, draw.GREEN)
