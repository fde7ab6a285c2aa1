"""Drawing primitives on RGB frames (OpenCV, anti-aliased)."""

from __future__ import annotations

import cv2
import numpy as np

# RGB colours of the lab-8 figure and the truth picture
GREEN, RED, DARK_RED, BLUE, GRAY, YELLOW = (0, 200, 0), (255, 0, 0), (120, 0, 0), (0, 80, 255), (150, 150, 150), (255, 210, 0)


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def plus(img: np.ndarray, p, color, size: int = 6, thickness: int = 1) -> None:
    cv2.drawMarker(img, _pt(p), color, cv2.MARKER_CROSS, size * 2, thickness, cv2.LINE_AA)


def cross(img: np.ndarray, p, color, size: int = 5, thickness: int = 1) -> None:
    cv2.drawMarker(img, _pt(p), color, cv2.MARKER_TILTED_CROSS, size * 2, thickness, cv2.LINE_AA)


def dot(img: np.ndarray, p, color, radius: int = 2) -> None:
    cv2.circle(img, _pt(p), radius, color, -1, cv2.LINE_AA)


def ring(img: np.ndarray, p, color, radius: int = 4) -> None:
    cv2.circle(img, _pt(p), radius, color, 1, cv2.LINE_AA)


def ellipse(img: np.ndarray, center, cov: np.ndarray, color, nsigma: float = 3.0, thickness: int = 1) -> None:
    """The ``nsigma`` confidence ellipse of a 2x2 covariance (eigen-decomposition of ``cov``)."""
    vals, vecs = np.linalg.eigh(cov)
    axes = nsigma * np.sqrt(np.maximum(vals, 0.0))
    angle = float(np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1])))
    big = max(img.shape) * 4
    size = (int(min(round(axes[1]), big)), int(min(round(axes[0]), big)))
    cv2.ellipse(img, _pt(center), size, angle, 0, 360, color, thickness, cv2.LINE_AA)


def label(img: np.ndarray, text: str, where=(6, 16), color=(255, 255, 255)) -> None:
    cv2.putText(img, text, where, cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(img, text, where, cv2.FONT_HERSHEY_SIMPLEX, 0.45, color, 1, cv2.LINE_AA)


def write_png(path, rgb: np.ndarray) -> None:
    """Write an RGB image atomically as PNG."""
    from ..atomic import atomic_path

    with atomic_path(path, suffix=".png") as tmp:
        if not cv2.imwrite(str(tmp), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
            raise OSError(f"cannot write {path}")
