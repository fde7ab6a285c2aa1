"""A top view of a closed-loop run (world x–y, seen from above) as an RGB image drawn with OpenCV,
to sit beside a camera frame: the true and estimated paths and cameras (heading: the optical axis on
the floor), the true landmarks (grey) and the map's with the 3σ ellipse of each x–y marginal (blue
confirmed, orange tentative), a key, a scale bar and a 1-2-5 grid. World to pixel is a similarity,
``u = u₀ + s (x − x₀)``, ``v = v₀ − s (y − y₀)``; a covariance ``C`` becomes ``D C Dᵀ``,
``D = diag(s, −s)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ...errors import UserError
from ...viz import draw

TRUE_COLOR, EST_COLOR = (20, 20, 20), (220, 30, 30)
LANDMARK_COLOR, GRID_COLOR, BACKGROUND = (150, 150, 150), (228, 228, 228), (255, 255, 255)
CONFIRMED_COLOR, TENTATIVE_COLOR = draw.BLUE, (255, 140, 0)
NSIGMA = 3.0
MARGIN = 0.12        # bounds: this share of the span (at least MIN_MARGIN_M) on every side
MIN_MARGIN_M = 0.25
MIN_SPAN_M = 1.0     # a degenerate scene (one point) still gets a metre of view
HEADING_PX = 16      # the heading arrow's length on screen, whatever the scale
FAR_PX = 1e5         # pixel coordinates are clipped here so a diverged estimate cannot overflow int32

Bounds = tuple[float, float, float, float]   # x_min, x_max, y_min, y_max in metres

TOPVIEW_LEGEND = (
    (lambda img, p: draw.dot(img, p, LANDMARK_COLOR, 2, halo=None), "true landmark"),
    (lambda img, p: (draw.ellipse(img, p, np.eye(2) * 4, CONFIRMED_COLOR),
                     draw.dot(img, p, CONFIRMED_COLOR, 2, halo=None)), "map, confirmed (3 sigma)"),
    (lambda img, p: (draw.ellipse(img, p, np.eye(2) * 4, TENTATIVE_COLOR),
                     draw.dot(img, p, TENTATIVE_COLOR, 2, halo=None)), "map, tentative (3 sigma)"),
    (lambda img, p: cv2.line(img, (p[0] - 8, p[1]), (p[0] + 8, p[1]), TRUE_COLOR, 3, cv2.LINE_AA), "true path, camera"),
    (lambda img, p: cv2.line(img, (p[0] - 8, p[1]), (p[0] + 8, p[1]), EST_COLOR, 1, cv2.LINE_AA), "estimate"),
)


def view_bounds(*points: np.ndarray, margin: float = MARGIN) -> Bounds:
    """x–y box around all ``points`` (finite rows), widened by ``margin`` of its span (at least
    ``MIN_MARGIN_M``); computed once per video so the picture does not jump."""
    xy = np.vstack([np.asarray(p, float).reshape(len(p), -1)[:, :2] for p in points if len(p)] or [np.zeros((0, 2))])
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if not len(xy):
        xy = np.zeros((1, 2))
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    centre, span = (lo + hi) / 2, np.maximum(hi - lo, MIN_SPAN_M)
    half = span / 2 + np.maximum(margin * span, MIN_MARGIN_M)
    return float(centre[0] - half[0]), float(centre[0] + half[0]), float(centre[1] - half[1]), float(centre[1] + half[1])


@dataclass(frozen=True)
class WorldToPixel:
    """The similarity that puts ``bounds`` in the middle of an image, as large as it fits (module docstring)."""

    scale: float      # pixels per metre, s
    u0: float
    v0: float
    x0: float
    y0: float

    @classmethod
    def fit(cls, bounds: Bounds, size: tuple[int, int], top: int = 0) -> WorldToPixel:
        """Fit ``bounds`` into the rows below ``top`` (the header: title and scale bar)."""
        h, w = size
        x_min, x_max, y_min, y_max = bounds
        s = min((w - 1) / (x_max - x_min), max(h - 1 - top, 1) / (y_max - y_min))
        return cls(s, (w - 1) / 2, top + (h - 1 - top) / 2, (x_min + x_max) / 2, (y_min + y_max) / 2)

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """(k, 2+) world points → (k, 2) pixels (x, y), clipped to ±``FAR_PX``."""
        xy = np.atleast_2d(np.asarray(xy, float))
        uv = np.column_stack([self.u0 + self.scale * (xy[:, 0] - self.x0), self.v0 - self.scale * (xy[:, 1] - self.y0)])
        return np.clip(uv, -FAR_PX, FAR_PX)

    def covariance(self, C: np.ndarray) -> np.ndarray:
        """A 2×2 x–y covariance in pixels: ``D C Dᵀ``, ``D = diag(s, −s)``."""
        D = np.diag([self.scale, -self.scale])
        return D @ C @ D.T


def nice_length(target: float) -> float:
    """The largest 1, 2 or 5 × 10ᵏ not above ``target`` (> 0): a round scale-bar length or grid step."""
    k = np.floor(np.log10(target))
    for m in (5.0, 2.0, 1.0):
        if m * 10 ** k <= target:
            return float(m * 10 ** k)
    return float(10 ** k)


def _grid(img: np.ndarray, T: WorldToPixel, step: float, top: int) -> None:
    """Light lines every ``step`` metres (the scale bar's length), below the header row ``top``."""
    h, w = img.shape[:2]
    x_lo, x_hi = T.x0 - T.u0 / T.scale, T.x0 + (w - 1 - T.u0) / T.scale
    y_lo, y_hi = T.y0 - (h - 1 - T.v0) / T.scale, T.y0 + T.v0 / T.scale
    for x in np.arange(np.ceil(x_lo / step) * step, x_hi, step):
        u = int(round(T(np.array([[x, 0.0]]))[0, 0]))
        cv2.line(img, (u, top), (u, h - 1), GRID_COLOR, 1)
    for y in np.arange(np.ceil(y_lo / step) * step, y_hi, step):
        v = int(round(T(np.array([[0.0, y]]))[0, 1]))
        if v >= top:
            cv2.line(img, (0, v), (w - 1, v), GRID_COLOR, 1)


def _scale_bar(img: np.ndarray, T: WorldToPixel, length: float, top: int) -> int:
    """A bar of ``length`` metres at the top left below ``top``, labelled; the key takes another
    corner."""
    scale = draw.text_scale(img)
    (_, th), _ = cv2.getTextSize("0", draw.FONT, scale, 1)
    x0, y = 10, top + th + 14
    x1 = x0 + int(round(length * T.scale))
    cv2.line(img, (x0, y), (x1, y), TRUE_COLOR, 2)
    for x in (x0, x1):
        cv2.line(img, (x, y - 4), (x, y + 4), TRUE_COLOR, 2)
    text = f"{length:g} m"
    (tw, _), _ = cv2.getTextSize(text, draw.FONT, scale, 1)
    cv2.putText(img, text, ((x0 + x1 - tw) // 2, y - 7), draw.FONT, scale, TRUE_COLOR, 1, cv2.LINE_AA)
    return y + 6


def _path(img: np.ndarray, uv: np.ndarray, color, thickness: int) -> None:
    """A polyline through the finite points (sub-pixel positions: 4 fractional bits)."""
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) >= 2:
        cv2.polylines(img, [np.round(uv * 16).astype(np.int32)], False, color, thickness, cv2.LINE_AA, shift=4)


def _camera(img: np.ndarray, T: WorldToPixel, p: np.ndarray, R: np.ndarray | None, color, radius: int) -> None:
    """The camera at ``p``: a ring and an arrow along its optical axis on x–y (none looking straight
    up or down)."""
    if not np.all(np.isfinite(p)):
        return
    c = T(p[None])[0]
    draw.ring(img, c, color, radius=radius, thickness=2, halo=BACKGROUND)
    if R is None:
        return
    f = np.asarray(R, float)[:2, 2]
    norm = float(np.hypot(*f))
    if not np.isfinite(norm) or norm < 1e-6:
        return
    tip = c + HEADING_PX * np.array([f[0], -f[1]]) / norm   # image rows grow downwards
    cv2.arrowedLine(img, draw._pt(c), draw._pt(tip), color, 2, cv2.LINE_AA, tipLength=0.35)


def _map(img: np.ndarray, T: WorldToPixel, means: np.ndarray, covs: np.ndarray, confirmed: np.ndarray) -> None:
    """Each map landmark's mean and 3σ ellipse of ``C[:2, :2]``, tentative first so confirmed are on
    top; non-finite entries skipped."""
    uv = T(means) if len(means) else np.zeros((0, 2))
    for want in (False, True):
        color = CONFIRMED_COLOR if want else TENTATIVE_COLOR
        for j in np.flatnonzero(np.asarray(confirmed, bool) == want):
            C = covs[j, :2, :2]
            if not (np.all(np.isfinite(uv[j])) and np.all(np.isfinite(C))):
                continue
            draw.ellipse(img, uv[j], T.covariance((C + C.T) / 2), color, nsigma=NSIGMA)
            draw.dot(img, uv[j], color, 2, halo=None)


def _text_width(h: int, w: int) -> int:
    """Width ``draw.text_scale`` sizes the words by: at most 4/3 of the height, so a wide view
    writes as small as the camera frame beside it."""
    return min(w, int(round(4 * h / 3)))


def _key(img: np.ndarray, points: list[np.ndarray]) -> None:
    """The key in the corner (bottom left, bottom right, top right) covering the fewest ``points``,
    sized as on a ``_text_width`` wide image."""
    h, w = img.shape[:2]
    vw = _text_width(h, w)
    box = draw.legend_box(img[:, :vw], TOPVIEW_LEGEND)   # for its size only
    if box is None:
        return
    bw, bh = box[2] - box[0], box[3] - box[1]
    pts = np.vstack(points) if points else np.zeros((0, 2))

    def covered(c):
        return int(np.sum((pts[:, 0] >= c[0]) & (pts[:, 0] <= c[0] + bw) & (pts[:, 1] >= c[1]) & (pts[:, 1] <= c[1] + bh)))

    x, y = min([(4, h - 4 - bh), (w - 4 - bw, h - 4 - bh), (w - 4 - bw, 4)], key=covered)
    x0 = 0 if x + bw <= vw else w - vw   # the text-width view that holds the box (a view: draws on img)
    draw.legend(img[:, x0:x0 + vw], TOPVIEW_LEGEND, (x - x0, y, x - x0 + bw, y + bh))


def _check(size: tuple[int, int], bounds: Bounds | None, n: tuple[int, int, int]) -> None:
    """One line naming what is wrong: a size without pixels, an empty or non-finite box, map arrays
    of unequal length."""
    if min(size) < 1:
        raise UserError(f"top view size must be (height, width) of at least 1 pixel each, got {size}")
    if bounds is not None and not (np.all(np.isfinite(bounds)) and bounds[1] > bounds[0] and bounds[3] > bounds[2]):
        raise UserError(f"top view bounds must be finite (x_min, x_max, y_min, y_max) with x_min < x_max and "
                        f"y_min < y_max, got {bounds}")
    if len(set(n)) > 1:
        raise UserError(f"top view map: {n[0]} means, {n[1]} covariances and {n[2]} confirmed flags; give one "
                        f"of each per landmark")


def top_view(true_p: np.ndarray, est_p: np.ndarray, est_R: np.ndarray | None, landmarks_true: np.ndarray,
             map_means: np.ndarray, map_covs: np.ndarray, confirmed: np.ndarray, size: tuple[int, int] = (480, 480),
             bounds: Bounds | None = None, true_R: np.ndarray | None = None, title: str = "") -> np.ndarray:
    """The top view as an (h, w, 3) uint8 RGB image, ``size = (h, w)``. ``true_p``, ``est_p``: (k,
    3) positions (the last is the current camera); ``est_R``, ``true_R``: current rotations (None:
    no arrow); ``landmarks_true`` (L, 3); ``map_means`` (N, 3), ``map_covs`` (N, 3, 3),
    ``confirmed`` (N,); ``bounds`` (metres), default ``view_bounds(true_p, landmarks_true)`` (pass
    one box for a video)."""
    h, w = int(size[0]), int(size[1])
    true_p, est_p = np.asarray(true_p, float).reshape(-1, 3), np.asarray(est_p, float).reshape(-1, 3)
    landmarks_true = np.asarray(landmarks_true, float).reshape(-1, 3)
    map_means = np.asarray(map_means, float).reshape(-1, 3)
    map_covs = np.asarray(map_covs, float).reshape(-1, 3, 3)
    _check((h, w), bounds, (len(map_means), len(map_covs), len(np.atleast_1d(confirmed))))
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    left = img[:, :_text_width(h, w)]   # a view: words sized as on the camera frame
    y = draw.label(left, title) if title else 4
    # the header (title, scale bar) is kept clear of the map: the world is fitted below it
    header = y + 2 * cv2.getTextSize("0", draw.FONT, draw.text_scale(left), 1)[0][1] + 16
    T = WorldToPixel.fit(bounds or view_bounds(true_p, landmarks_true), (h, w), top=header)
    bar = nice_length(0.25 * left.shape[1] / T.scale)
    _grid(img, T, bar, header)
    y = _scale_bar(left, T, bar, y)
    _key(img, [T(p) for p in (true_p, est_p, landmarks_true, map_means) if len(p)])
    for c in T(landmarks_true):
        draw.dot(img, c, LANDMARK_COLOR, 1, halo=None)
    _map(img, T, map_means, map_covs, confirmed)
    _path(img, T(true_p), TRUE_COLOR, 3)   # wide under thin: both show where they coincide
    _path(img, T(est_p), EST_COLOR, 1)
    if len(true_p):
        _camera(img, T, true_p[-1], true_R, TRUE_COLOR, 7)   # the larger ring, under the estimate's
    if len(est_p):
        _camera(img, T, est_p[-1], est_R, EST_COLOR, 4)
        u, v = T(est_p[-1:])[0]
        if np.all(np.isfinite(est_p[-1])) and not (0 <= u < w and 0 <= v < h):
            draw.label(left, "estimated camera outside the view", (4, y + 2), background=(200, 0, 0))
    return img
