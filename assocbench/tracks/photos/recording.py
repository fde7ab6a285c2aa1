"""A Bundler reconstruction made ready for association: its landmarks (points, duplicates merged),
each image's keypoints, and the reference pairing them.

**Reference.** The key files shipped beside Balbianello are not those the bundle's key indices refer
to, so each view is matched to a keypoint by position: view ``(x, y)`` is pixel
``(x + (W-1)/2, (H-1)/2 - y)``, its keypoint the nearest within ``match_radius``, one-to-one per
image, nearest pairs first; a view without one pairs with nothing.

**Duplicates.** SIFT emits a keypoint per dominant orientation and Bundler a point per orientation,
so points sharing a view position (within 0.01 px) and agreeing within ``match_radius`` in every
image both see are one landmark; all keypoints at its spot carry its label.

**Appearance.** A landmark's descriptor for frame ``i`` is the mean of its spots' descriptors in the
other images: one row per landmark that finds the right spot about as often as the nearest of the
set.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...models.bundler import BundlerCamera
from .files import Bundle, Keys

SAME_SPOT_PX = 0.01   # two positions closer than this are one spot (the files give two decimals)


@dataclass(frozen=True)
class MatchReport:
    """How the views matched: ``views``, ``within`` the radius, ``median_px`` to the nearest
    keypoint, bundle ``points`` and merged ``landmarks``, reference pairs per image."""

    views: int
    within: int
    median_px: float
    radius_px: float
    points: int
    landmarks: int
    pairs: tuple[int, ...]

    def line(self) -> str:
        """One line for a page or a log."""
        return (f"{self.within} of {self.views} views ({100 * self.within / max(self.views, 1):.1f} %) lie within "
                f"{self.radius_px:g} px of a keypoint (median {self.median_px:.2f} px); {self.points} points merged "
                f"into {self.landmarks} landmarks; reference pairs per image {list(self.pairs)}")


@dataclass(frozen=True)
class Photo:
    """One image: its ``camera``, ``keys``, each keypoint's ``labels`` (landmark or -1), and per
    landmark ``seen`` here, its ``reference`` keypoint (-1: none) and
    ``descriptor_sum``/``descriptor_count`` at its spot."""

    image: Path
    camera: BundlerCamera
    keys: Keys
    labels: np.ndarray
    seen: np.ndarray
    reference: np.ndarray
    descriptor_sum: np.ndarray
    descriptor_count: np.ndarray


@dataclass(frozen=True)
class Recording:
    """A reconstruction ready for association: ``landmarks`` (L, 3), its ``photos`` and how its views
    matched (``report``)."""

    landmarks: np.ndarray
    photos: tuple[Photo, ...]
    report: MatchReport

    def landmark_descriptors(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Each landmark's mean descriptor over the images other than ``i`` (L, D) float32, and
        whether it has one."""
        others = [p for k, p in enumerate(self.photos) if k != i]
        total = sum(p.descriptor_sum for p in others)
        count = sum(p.descriptor_count for p in others)
        has = count > 0
        mean = np.zeros_like(total, dtype=np.float32)
        mean[has] = total[has] / count[has, None]
        return mean, has


def merge_duplicates(bundle: Bundle, radius: float) -> np.ndarray:
    """(N,) landmark of each bundle point: points sharing a view position and agreeing within
    ``radius`` px in every common image are one."""
    parent = np.arange(len(bundle.points))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    spots: dict[tuple, list[int]] = {}
    for p, views in enumerate(bundle.views):
        for cam, _, x, y in views:
            spots.setdefault((int(cam), round(x / SAME_SPOT_PX), round(y / SAME_SPOT_PX)), []).append(p)
    for points in spots.values():
        for a in points[1:]:
            if _agree(bundle.views[points[0]], bundle.views[a], radius):
                parent[root(a)] = root(points[0])
    roots = np.array([root(p) for p in range(len(parent))])
    return np.unique(roots, return_inverse=True)[1].ravel()


def _agree(a: np.ndarray, b: np.ndarray, radius: float) -> bool:
    """Whether two view lists lie within ``radius`` px of each other in every image both name."""
    for cam, _, x, y in a:
        same = b[b[:, 0] == cam]
        if len(same) and np.hypot(same[0, 2] - x, same[0, 3] - y) > radius:
            return False
    return True


def landmark_views(bundle: Bundle, owner: np.ndarray, cameras: int) -> np.ndarray:
    """(L, cameras, 2) mean view position of each landmark in each image, NaN where unseen."""
    total = np.zeros((owner.max(initial=-1) + 1, cameras, 2))
    count = np.zeros(total.shape[:2])
    for p, views in enumerate(bundle.views):
        cams = views[:, 0].astype(int)
        np.add.at(total, (owner[p], cams), views[:, 2:])
        np.add.at(count, (owner[p], cams), 1.0)
    with np.errstate(invalid="ignore"):
        return total / count[:, :, None]


@dataclass(frozen=True)
class Spots:
    """An image's distinct keypoint positions: ``pixels`` (s, 2), each keypoint's spot ``of_key``,
    each spot's ``first_key``."""

    pixels: np.ndarray
    of_key: np.ndarray
    first_key: np.ndarray


def spots_of(keys: Keys) -> Spots:
    """The spots of an image's keypoints (positions within ``SAME_SPOT_PX`` are one)."""
    grid = np.round(keys.pixels / SAME_SPOT_PX).astype(np.int64)
    _, first, spot = np.unique(grid, axis=0, return_index=True, return_inverse=True)
    return Spots(keys.pixels[first], spot.ravel(), first)


def match_views(views_px: np.ndarray, spots: np.ndarray, radius: float) -> np.ndarray:
    """The spot (L,) each view (NaN: unseen) is paired with, -1 for none within ``radius``;
    one-to-one, nearest first."""
    from scipy.spatial import cKDTree

    seen = np.flatnonzero(np.isfinite(views_px[:, 0]))
    paired = np.full(len(views_px), -1, np.int64)
    if not len(seen) or not len(spots):
        return paired
    candidates = cKDTree(spots).query_ball_point(views_px[seen], radius)
    pairs = sorted((float(np.hypot(*(spots[s] - views_px[v]))), int(v), int(s))
                   for v, near in zip(seen, candidates) for s in near)
    taken: set[int] = set()
    for _, v, s in pairs:
        if paired[v] < 0 and s not in taken:
            paired[v] = s
            taken.add(s)
    return paired


def build_recording(bundle: Bundle, keys: list[Keys], images: list[Path], cameras: list[BundlerCamera],
                    radius: float) -> Recording:
    """The reconstruction's landmarks, photos and reference (module docstring)."""
    owner = merge_duplicates(bundle, radius)
    count = owner.max(initial=-1) + 1
    landmarks = np.zeros((count, 3))
    np.add.at(landmarks, owner, bundle.points)
    landmarks /= np.bincount(owner, minlength=count)[:, None]
    views = landmark_views(bundle, owner, len(cameras))
    photos, distances = [], []
    for c, (k, camera) in enumerate(zip(keys, cameras)):
        spots = spots_of(k)
        view_px = np.full((count, 2), np.nan)
        seen = np.isfinite(views[:, c, 0])
        view_px[seen] = camera.to_pixels(views[seen, c])
        photos.append(_photo(images[c], camera, k, spots, seen, match_views(view_px, spots.pixels, radius)))
        distances.append(_raw_view_distances(bundle, c, camera, spots.pixels))
    near = np.concatenate(distances)
    report = MatchReport(bundle.observations, int(np.sum(near <= radius)), float(np.median(near)) if len(near) else np.nan,
                         radius, len(bundle.points), count, tuple(int(np.sum(p.reference >= 0)) for p in photos))
    return Recording(landmarks, tuple(photos), report)


def _photo(image: Path, camera: BundlerCamera, keys: Keys, spots: Spots, seen: np.ndarray,
           paired_spot: np.ndarray) -> Photo:
    """One image's labels, reference (its spot's first keypoint) and descriptor sums."""
    count = len(seen)
    owner_of_spot = np.full(len(spots.pixels), -1, np.int64)
    has = paired_spot >= 0
    owner_of_spot[paired_spot[has]] = np.flatnonzero(has)
    labels = owner_of_spot[spots.of_key]
    reference = np.full(count, -1, np.int64)
    reference[has] = spots.first_key[paired_spot[has]]
    descriptor_sum = np.zeros((count, keys.descriptors.shape[1]))
    labelled = labels >= 0
    np.add.at(descriptor_sum, labels[labelled], keys.descriptors[labelled].astype(np.float64))
    descriptor_count = np.bincount(labels[labelled], minlength=count).astype(np.float64)
    return Photo(image, camera, keys, labels, seen, reference, descriptor_sum, descriptor_count)


def _raw_view_distances(bundle: Bundle, c: int, camera: BundlerCamera, spot_px: np.ndarray) -> np.ndarray:
    """Distance of every view of the bundle in image ``c`` (before merging) to its nearest keypoint."""
    from scipy.spatial import cKDTree

    xy = np.concatenate([v[v[:, 0] == c, 2:] for v in bundle.views]) if bundle.views else np.zeros((0, 2))
    if not len(xy) or not len(spot_px):
        return np.full(len(xy), np.inf)
    return cKDTree(spot_px).query(camera.to_pixels(xy))[0]
