"""Corner detection with OpenCV: Shi-Tomasi (default), FAST or ORB, refined by ``cornerSubPix``."""

from __future__ import annotations

import cv2
import numpy as np

from .settings import DetectorConfig


def _raw_corners(gray: np.ndarray, cfg: DetectorConfig) -> np.ndarray:
    if cfg.method == "shi-tomasi":
        pts = cv2.goodFeaturesToTrack(gray, cfg.max_features, cfg.quality, cfg.min_distance, blockSize=5)
        return np.zeros((0, 2), np.float32) if pts is None else pts.reshape(-1, 2)
    if cfg.method == "fast":
        kps = cv2.FastFeatureDetector_create(threshold=20, nonmaxSuppression=True).detect(gray)
    else:
        kps = cv2.ORB_create(nfeatures=cfg.max_features).detect(gray)
    kps = sorted(kps, key=lambda k: -k.response)[: cfg.max_features]
    return np.array([k.pt for k in kps], np.float32).reshape(-1, 2)


def _drop_duplicates(pts: np.ndarray, radius: float = 1.0) -> np.ndarray:
    """Keep the strongest of corners sub-pixel refinement pulled together: two raw corners near an
    X-junction converge onto it, and the second would be unlabelled "clutter" on the landmark.
    """
    if len(pts) < 2:
        return pts
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    close_to_earlier = np.triu(d < radius, k=1).any(axis=0)
    return pts[~close_to_earlier]


def detect(rgb: np.ndarray, cfg: DetectorConfig, rng: np.random.Generator | None = None) -> np.ndarray:
    """Feature pixel coordinates (m, 2) float64, sorted by row then column for determinism."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    pts = _raw_corners(gray, cfg)
    if len(pts) and cfg.subpix_window > 0:
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 40, 0.001)
        win = (cfg.subpix_window, cfg.subpix_window)
        pts = cv2.cornerSubPix(gray, np.ascontiguousarray(pts), win, (-1, -1), criteria)
    pts = _drop_duplicates(pts.astype(np.float64))
    if cfg.noise_px > 0 and len(pts):
        rng = rng if rng is not None else np.random.default_rng(0)
        pts = pts + rng.normal(0.0, cfg.noise_px, pts.shape)
    order = np.lexsort((pts[:, 0], pts[:, 1])) if len(pts) else np.arange(0)
    return pts[order]
