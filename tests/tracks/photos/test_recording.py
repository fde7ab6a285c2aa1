"""The reference of a Bundler reconstruction: duplicates merged, views matched to keypoints by position,
one-to-one, keypoints at one spot labelled together; and Balbianello's figures."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.models.bundler import BundlerCamera
from assocbench.tracks.photos.files import Bundle, BundleCamera, Keys
from assocbench.tracks.photos.recording import build_recording, merge_duplicates

CAM = BundleCamera(100.0, 0.0, 0.0, np.eye(3), np.zeros(3))


def bundle(views: list[list[tuple]]) -> Bundle:
    """Points at the origin (their positions do not matter here) with the given views (camera, x, y)."""
    arrays = tuple(np.array([(c, 0, x, y) for c, x, y in v], float) for v in views)
    return Bundle((CAM, CAM), np.arange(3 * len(views), dtype=float).reshape(-1, 3), np.zeros((len(views), 3)), arrays)


def keys(pixels: list[tuple], descriptors: list[list[int]]) -> Keys:
    px = np.array(pixels, float)
    return Keys(px[:, 1], px[:, 0], np.ones(len(px)), np.zeros(len(px)), np.array(descriptors, np.uint8))


def test_points_sharing_a_view_and_agreeing_elsewhere_are_one_landmark():
    b = bundle([[(0, 10, 5), (1, 3, 3)],            # A
                [(0, 10, 5), (1, 3.8, 3)],          # B: A's view in camera 0, 0.8 px from it in camera 1: A
                [(0, -20, 0), (1, 7, 7)],           # C
                [(0, -20, 0), (1, 17, 7)],          # D: C's view in camera 0 but 10 px off in camera 1: not C
                [(1, 3, 3.01)]])                    # E: near A in camera 1 only, sharing no view: not A
    owner = merge_duplicates(b, radius=1.5)
    assert owner[0] == owner[1] and len(set(owner.tolist())) == 4


def test_views_match_keypoints_one_to_one_and_twins_share_the_label():
    """Image 100 x 100 (centre 49.5, 49.5): A's view (10, 5) is the pixel (59.5, 44.5), where two keypoints
    sit (two orientations); F's view 1 px from G's keypoint and G's 0.2 px from it: G has it, F has none."""
    b = bundle([[(0, 10, 5), (1, 0, 0)],               # A
                [(0, -10, -10), (1, 20, 20)],          # F: pixel (39.5, 59.5)
                [(0, -10.8, -10), (1, 30, 30)]])       # G: pixel (38.7, 59.5)
    k0 = keys([(59.5, 44.5), (59.5, 44.5), (38.5, 59.5), (5, 5)], [[1, 0], [3, 0], [0, 8], [9, 9]])
    k1 = keys([(49.5, 49.5), (69.5, 29.5), (79.5, 19.5)], [[2, 2], [4, 4], [6, 6]])
    cam = BundlerCamera(100.0, 0.0, 0.0, np.eye(3), np.zeros(3), 100, 100)
    rec = build_recording(b, [k0, k1], ["a.jpg", "b.jpg"], [cam, cam], radius=1.5)
    first = rec.photos[0]
    assert first.labels.tolist() == [0, 0, 2, -1]          # A on both twins, G on its keypoint, F on none
    assert first.reference.tolist() == [0, -1, 2] and first.seen.tolist() == [True, True, True]
    assert rec.report.views == 6 and rec.report.within == 6 and rec.report.pairs == (2, 3)
    mean, has = rec.landmark_descriptors(1)                 # from image 0 only: A's twins averaged
    assert has.tolist() == [True, False, True]
    np.testing.assert_allclose(mean[0], [2, 0])
    np.testing.assert_allclose(mean[2], [0, 8])
    mean, has = rec.landmark_descriptors(0)                 # from image 1: every landmark's one keypoint
    assert has.tolist() == [True, True, True] and mean[1].tolist() == [4, 4]


def test_balbianello_views_match_their_keypoints_as_measured():
    """83 % of the bundle's views within 1.5 px of a keypoint, median 0.27 px; 544 points, one per
    SIFT orientation at a spot, are 470 landmarks."""
    pytest.importorskip("gtsam")
    from assocbench.tracks.photos.source import balbianello, read_recording

    rec = read_recording(balbianello(), 1.5)
    r = rec.report
    assert (r.views, r.within, r.points, r.landmarks) == (1417, 1174, 544, 470)
    assert r.median_px == pytest.approx(0.27, abs=0.01)
    assert r.pairs == (208, 271, 262, 202, 75)
    for p in rec.photos:   # every reference pair is a labelled keypoint of its landmark
        j = np.flatnonzero(p.reference >= 0)
        assert np.array_equal(p.labels[p.reference[j]], j)
