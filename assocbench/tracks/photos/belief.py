"""The photos track's association problem of one image: the map holds the landmarks seen with a
keypoint in the *other* images (``PhotoFrame.in_map``); the estimate is the bundle's camera and
landmarks plus an error drawn from ``k² Σ`` (Σ as on the camera track,
``belief.config.sample_estimate``); candidates are the map landmarks the estimated camera sees,
predicted through the Bundler projection (``models.bundler``) with ``P = J Σ Jᵀ``. Measurements are
every keypoint of the image, most of them clutter; the reference labels the keypoints at each
landmark's view (``recording``).
"""

from __future__ import annotations

import numpy as np

from ...association.problem import Problem
from ...association.truth import FrameTruth
from ...belief.config import BeliefConfig, map_mask, prediction_covariance, sample_estimate, true_association
from ...models.bundler import predict_bundle
from .source import PhotoFrame

STREAM = 303   # this track's stream of the run's seed


def make_photo_problem(frame: PhotoFrame, cfg: BeliefConfig, seed: int) -> tuple[Problem, FrameTruth]:
    """Frame ``frame.index``'s problem and its reference (module docstring)."""
    photo, camera = frame.photo, frame.photo.camera
    rng = np.random.default_rng([seed, frame.index, STREAM])
    C, p, landmarks = sample_estimate(camera.orientation, camera.centre, frame.landmarks, cfg, rng)
    h, J_pose, J_l, depth = predict_bundle(C, p, landmarks, camera)
    in_map = frame.in_map & map_mask(len(landmarks), cfg, seed)
    in_front = depth > 1e-9
    cand = np.flatnonzero(in_map & in_front & camera.in_image(np.where(in_front[:, None], h, -1e9)))
    z = photo.keys.pixels
    problem = Problem(z=z, R=np.repeat((cfg.sigma_pixel**2 * np.eye(2))[None], len(z), axis=0),
                      zhat=h[cand], P=prediction_covariance(J_pose[cand], J_l[cand], cfg.pose_covariance, cfg),
                      landmark_ids=cand, volume=camera.area, descriptors=photo.keys.descriptors,
                      landmark_descriptors=frame.descriptors[cand])
    labels = np.where((photo.labels >= 0) & in_map[np.maximum(photo.labels, 0)], photo.labels, -1).astype(np.int64)
    return problem, FrameTruth(labels, true_association(labels, cand), photo.seen[cand])
