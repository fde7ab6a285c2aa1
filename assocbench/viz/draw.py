"""Drawing primitives on RGB frames (OpenCV, anti-aliased). Markers have a contrasting outline
(``halo``) and text a dark backing box: on grey walls, checkers and white patches a plain mark
vanishes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from ..errors import UserError

# RGB colours of the lab-8 figure and the truth picture
GREEN, RED, DARK_RED, BLUE, YELLOW = (0, 200, 0), (255, 0, 0), (120, 0, 0), (0, 80, 255), (255, 210, 0)
MAGENTA, BLACK, WHITE = (255, 0, 255), (0, 0, 0), (255, 255, 255)
FONT = cv2.FONT_HERSHEY_SIMPLEX
# what cv2.imwrite can write from an 8-bit RGB frame without losing colour, by extension
IMAGE_FORMATS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")

Marker = Callable[[np.ndarray, tuple[int, int]], None]


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def plus(img: np.ndarray, p, color, size: int = 6, thickness: int = 1, halo=BLACK) -> None:
    """A ``+`` of half-width ``size`` at ``p`` (x, y), outlined in ``halo`` (None: no outline)."""
    if halo is not None:
        cv2.drawMarker(img, _pt(p), halo, cv2.MARKER_CROSS, size * 2 + 2, thickness + 2, cv2.LINE_AA)
    cv2.drawMarker(img, _pt(p), color, cv2.MARKER_CROSS, size * 2, thickness, cv2.LINE_AA)


def cross(img: np.ndarray, p, color, size: int = 5, thickness: int = 1, halo=BLACK) -> None:
    """An ``×`` of half-width ``size`` at ``p``, outlined in ``halo`` (None: no outline)."""
    if halo is not None:
        cv2.drawMarker(img, _pt(p), halo, cv2.MARKER_TILTED_CROSS, size * 2 + 2, thickness + 2, cv2.LINE_AA)
    cv2.drawMarker(img, _pt(p), color, cv2.MARKER_TILTED_CROSS, size * 2, thickness, cv2.LINE_AA)


def dot(img: np.ndarray, p, color, radius: int = 2, halo=WHITE) -> None:
    """A filled dot; the light ring keeps a dark dot visible on black."""
    if halo is not None:
        cv2.circle(img, _pt(p), radius + 1, halo, -1, cv2.LINE_AA)
    cv2.circle(img, _pt(p), radius, color, -1, cv2.LINE_AA)


def ring(img: np.ndarray, p, color, radius: int = 4, thickness: int = 1, halo=BLACK) -> None:
    """An open circle; the dark outline keeps a light ring visible on white."""
    if halo is not None:
        cv2.circle(img, _pt(p), radius, halo, thickness + 2, cv2.LINE_AA)
    cv2.circle(img, _pt(p), radius, color, thickness, cv2.LINE_AA)


def ellipse(img: np.ndarray, center, cov: np.ndarray, color, nsigma: float = 3.0, thickness: int = 1) -> None:
    """The ``nsigma`` confidence ellipse of a 2x2 covariance (eigen-decomposition of ``cov``)."""
    vals, vecs = np.linalg.eigh(cov)
    axes = nsigma * np.sqrt(np.maximum(vals, 0.0))
    angle = float(np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1])))
    big = max(img.shape) * 4
    size = (int(min(round(axes[1]), big)), int(min(round(axes[0]), big)))
    cv2.ellipse(img, _pt(center), size, angle, 0, 360, color, thickness, cv2.LINE_AA)


def text_scale(img: np.ndarray) -> float:
    """Font scale for an image: 0.45 at 640 px wide, between 0.3 and 0.7."""
    return float(np.clip(img.shape[1] / 1420, 0.3, 0.7))


def shade(img: np.ndarray, x0: int, y0: int, x1: int, y1: int, color=BLACK, alpha: float = 0.65) -> None:
    """Blend ``color`` over the box [x0, x1) × [y0, y1) in place (clipped to the image)."""
    h, w = img.shape[:2]
    x0, x1, y0, y1 = max(x0, 0), min(x1, w), max(y0, 0), min(y1, h)
    if x1 > x0 and y1 > y0:
        box = img[y0:y1, x0:x1].astype(np.float32)
        img[y0:y1, x0:x1] = np.rint(box * (1 - alpha) + np.float32(color) * alpha).astype(np.uint8)


def label(img: np.ndarray, text: str, where=(4, 4), color=WHITE, background=BLACK) -> int:
    """Write ``text`` on a backing box from ``where``; returns the box's bottom y. Text wider than
    the image ends in ``...``."""
    scale = text_scale(img)
    pad = max(2, int(round(4 * scale / 0.45)))
    x, y = int(where[0]), int(where[1])
    room = img.shape[1] - x - 2 * pad
    while len(text) > 4 and cv2.getTextSize(text, FONT, scale, 1)[0][0] > room:
        text = text[:-4] + "..."
    (w, h), base = cv2.getTextSize(text, FONT, scale, 1)
    shade(img, x, y, x + w + 2 * pad, y + h + base + 2 * pad, background, 0.7)
    cv2.putText(img, text, (x + pad, y + pad + h), FONT, scale, color, 1, cv2.LINE_AA)
    return y + h + base + 2 * pad


def legend_box(img: np.ndarray, entries: Sequence[tuple[Marker, str]],
               avoid: np.ndarray | None = None) -> tuple[int, int, int, int] | None:
    """The key's box (x0, y0, x1, y1): the bottom or top-right corner holding the fewest ``avoid``
    points; None if it would cover over half the width or a third of the height."""
    scale = text_scale(img) * 0.9
    sizes = [cv2.getTextSize(text, FONT, scale, 1)[0] for _, text in entries]
    row = max(h for _, h in sizes) + max(6, int(10 * scale / 0.4))
    w = row + 12 + max(w for w, _ in sizes)
    h = row * len(entries) + 6
    H, W = img.shape[:2]
    if w > W / 2 or h > H / 3:
        return None
    corners = [(4, H - 4 - h), (W - 4 - w, H - 4 - h), (W - 4 - w, 4)]
    pts = np.zeros((0, 2)) if avoid is None else np.asarray(avoid, float).reshape(-1, 2)

    def inside(c):
        return int(np.sum((pts[:, 0] >= c[0]) & (pts[:, 0] <= c[0] + w) & (pts[:, 1] >= c[1]) & (pts[:, 1] <= c[1] + h)))

    x, y = min(corners, key=inside)   # min keeps the first corner on ties: bottom-left by default
    return x, y, x + w, y + h


def legend(img: np.ndarray, entries: Sequence[tuple[Marker, str]], box=None) -> None:
    """A compact key, a row per entry with its marker, on a dark ``box``; drawn before the data so
    no marker is hidden."""
    box = box or legend_box(img, entries)
    if box is None:
        return
    x0, y0, x1, y1 = box
    shade(img, x0, y0, x1, y1, BLACK, 0.75)
    scale = text_scale(img) * 0.9
    row = (y1 - y0 - 6) // len(entries)
    for k, (marker, text) in enumerate(entries):
        cy = y0 + 3 + row * k + row // 2
        marker(img, (x0 + row // 2 + 4, cy))
        (_, h), _ = cv2.getTextSize(text, FONT, scale, 1)
        cv2.putText(img, text, (x0 + row + 8, cy + h // 2), FONT, scale, WHITE, 1, cv2.LINE_AA)


def check_image_path(path) -> Path:
    """Refuse an output path that is a folder or whose extension names no image format we write."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"-o {path} is a folder: give a file name such as {path / 'frame.png'}")
    if path.suffix.lower() not in IMAGE_FORMATS or not cv2.haveImageWriter(str(path)):
        raise UserError(f"cannot write an image named {path.name!r}: use one of {', '.join(IMAGE_FORMATS)}")
    return path


def write_image(path, rgb: np.ndarray) -> None:
    """Write an RGB image atomically in the format its extension names, encoded in memory, so a full
    disk or read-only folder is one line naming ``-o``."""
    from ..atomic import OUTPUT_FILE, atomic_path

    path = check_image_path(path)
    ok, data = cv2.imencode(path.suffix.lower(), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise UserError(f"OpenCV could not encode a {path.suffix} image; try a .png")
    with atomic_path(path, suffix=path.suffix, role=OUTPUT_FILE) as tmp:
        tmp.write_bytes(data.tobytes())

