"""The Bundler camera: the analytic Jacobians of the distorted projection against central differences,
and the projection against the views of a real reconstruction (Balbianello, in the gtsam package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from assocbench.models.bundler import BundlerCamera, predict_bundle
from assocbench.models.pinhole import exp_so3, perturb_pose


def camera(k1: float = -0.12, k2: float = 0.05) -> BundlerCamera:
    R = exp_so3(np.array([0.1, -0.25, 0.05]))
    return BundlerCamera(520.0, k1, k2, R, np.array([0.2, -0.1, 0.5]), 640, 427)


def scene(rng, cam: BundlerCamera, count: int = 8) -> np.ndarray:
    """Points 2-3 units in front of the camera, spread over most of the image (|q| up to 0.5, where
    the distortion terms matter)."""
    depth = rng.uniform(2.0, 3.0, count)
    q = rng.uniform(-0.5, 0.5, (count, 2))
    P = np.column_stack([q * depth[:, None], -depth])        # Bundler: in front is -z
    return (P - cam.t) @ cam.R                                 # X = Rᵀ (P - t)


@pytest.mark.parametrize("k1,k2", [(0.0, 0.0), (-0.12, 0.05), (0.3, -0.2)])
def test_analytic_jacobians_match_central_differences(rng, k1, k2):
    cam = camera(k1, k2)
    landmarks = scene(rng, cam)
    C, p = cam.orientation, cam.centre
    h, J_pose, J_l, depth = predict_bundle(C, p, landmarks, cam)
    assert np.all(depth > 0)
    eps = 1e-6
    for k in range(6):
        step = np.zeros(6)
        step[k] = eps
        plus, minus = perturb_pose(C, p, step[:3], step[3:]), perturb_pose(C, p, -step[:3], -step[3:])
        num = (predict_bundle(*plus, landmarks, cam)[0] - predict_bundle(*minus, landmarks, cam)[0]) / (2 * eps)
        assert np.abs(num - J_pose[:, :, k]).max() <= 1e-6 * np.abs(J_pose).max(), k
    for k in range(3):
        step = np.zeros(3)
        step[k] = eps
        num = (predict_bundle(C, p, landmarks + step, cam)[0] - predict_bundle(C, p, landmarks - step, cam)[0]) / (2 * eps)
        assert np.abs(num - J_l[:, :, k]).max() <= 1e-6 * np.abs(J_l).max(), k


def test_the_pixel_convention_puts_the_centre_at_half_the_size_less_half_a_pixel_and_rows_down():
    cam = camera(0.0, 0.0)
    ahead = (np.array([[0.0, 0.0, -2.0], [0.0, 0.2, -2.0], [0.2, 0.0, -2.0]]) - cam.t) @ cam.R
    h = predict_bundle(cam.orientation, cam.centre, ahead, cam)[0]
    np.testing.assert_allclose(h[0], [319.5, 213.0], atol=1e-9)
    assert h[1, 1] < h[0, 1] and h[2, 0] > h[0, 0]             # up in the camera is up in the image


def test_the_projection_lands_on_the_bundles_own_views():
    """Each of Balbianello's 1 417 views against its point projected by its camera: Bundler's own
    residuals (measured: median 0.13 px, 90 % within 0.42 px)."""
    from assocbench.tracks.photos.files import read_bundle

    bundle = read_bundle(Path(pytest.importorskip("gtsam").__file__).parent / "Data" / "Balbianello.out")
    errors = []
    for c, cam in enumerate(bundle.cameras):
        bc = BundlerCamera(cam.f, cam.k1, cam.k2, cam.R, cam.t, 640, 427)
        for X, views in zip(bundle.points, bundle.views):
            seen = views[views[:, 0] == c]
            if len(seen):
                h = predict_bundle(bc.orientation, bc.centre, X[None], bc)[0]
                errors.append(np.hypot(*(h[0] - bc.to_pixels(seen[0, 2:])[0])))
    assert len(errors) == 1417
    assert np.median(errors) < 0.2 and np.percentile(errors, 90) < 0.5
