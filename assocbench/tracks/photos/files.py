"""Readers of a Bundler reconstruction's two formats, the bundle (``bundle.out``, v0.3) and Lowe's
SIFT keypoint files (``.key``, ``.key.gz``); a malformed file is a one-line ``UserError`` naming
file, line and what was expected.

Bundle v0.3::

    # Bundle file v0.3
    <cameras> <points>
    <f> <k1> <k2>                     per camera: focal length (px), radial distortion
    <R: 3 lines of 3>                 world-to-camera rotation
    <t: 3 numbers>                    translation, P = R X + t
    <X Y Z>                           per point: position
    <r g b>                           colour
    <k> <camera key x y> × k          its views: camera index, key index in that camera's key file, and
                                      the position in pixels from the image centre, y up

Lowe's key file: ``<keys> <length>``, then per keypoint ``row column scale orientation`` and
``length`` descriptor bytes, whitespace-separated.
"""

from __future__ import annotations

import gzip
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import UserError


@dataclass(frozen=True)
class BundleCamera:
    """A camera as the file gives it: ``f``, ``k1``, ``k2``, ``R`` (3, 3), ``t`` (3,)."""

    f: float
    k1: float
    k2: float
    R: np.ndarray
    t: np.ndarray


@dataclass(frozen=True)
class Bundle:
    """A Bundler reconstruction: ``cameras``, ``points`` (N, 3), ``colours`` (N, 3) and ``views``,
    (k, 4) rows ``camera, key, x, y`` (from the image centre, y up)."""

    cameras: tuple[BundleCamera, ...]
    points: np.ndarray
    colours: np.ndarray
    views: tuple[np.ndarray, ...]

    @property
    def observations(self) -> int:
        """How many views all points have together."""
        return sum(len(v) for v in self.views)


@dataclass(frozen=True)
class Keys:
    """One image's SIFT keypoints: ``rows``, ``cols`` (top-left pixel's centre at 0, 0), ``scales``,
    ``orientations`` (rad) and ``descriptors`` (k, D) uint8."""

    rows: np.ndarray
    cols: np.ndarray
    scales: np.ndarray
    orientations: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def pixels(self) -> np.ndarray:
        """(k, 2) positions as (column, row), the measurements' order."""
        return np.column_stack([self.cols, self.rows])


class _Lines:
    """The numbers of a text file, line by line, for messages that name the line."""

    def __init__(self, path: Path, text: str) -> None:
        self.path, self.lines, self.at = path, text.splitlines(), 0

    def numbers(self, count: int, what: str, kind: type = float) -> list:
        """The next line's numbers: exactly ``count`` of ``kind``, or a one-line error."""
        if self.at >= len(self.lines):
            raise UserError(f"{self.path}: ends before {what} (line {self.at + 1}): the file is cut short")
        line, self.at = self.lines[self.at], self.at + 1
        try:
            values = [kind(v) for v in line.split()]
        except ValueError:
            values = []
        if len(values) != count or not np.all(np.isfinite(values)):
            raise UserError(f"{self.path} line {self.at}: expected {what} ({count} finite numbers), got {line.strip()!r}")
        return values

    def views(self) -> np.ndarray:
        """The next line as a view list ``k (camera key x y) × k``."""
        line = self.lines[self.at] if self.at < len(self.lines) else ""
        head = line.split()[:1]
        count = int(head[0]) if head and head[0].isdigit() else -1     # -1: no count, refused below
        values = self.numbers(1 + 4 * count, "a view list 'k, then camera key x y k times'")
        return np.array(values[1:], float).reshape(count, 4)


def read_bundle(path: str | Path) -> Bundle:
    """The reconstruction in a Bundler v0.3 file (module docstring)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read the bundle file {path}: {exc}") from None
    lines = _Lines(path, text)
    if not lines.lines or not lines.lines[0].startswith("# Bundle file v0.3"):
        raise UserError(f"{path} line 1: expected '# Bundle file v0.3' (a Bundler reconstruction)")
    lines.at = 1
    n_cameras, n_points = lines.numbers(2, "the counts '<cameras> <points>'", int)
    cameras = []
    for _ in range(n_cameras):
        f, k1, k2 = lines.numbers(3, "a camera's 'f k1 k2'")
        R = np.array([lines.numbers(3, "a row of a camera's rotation") for _ in range(3)])
        t = np.array(lines.numbers(3, "a camera's translation"))
        cameras.append(BundleCamera(f, k1, k2, R, t))
    points, colours, views = np.zeros((n_points, 3)), np.zeros((n_points, 3)), []
    for p in range(n_points):
        points[p] = lines.numbers(3, "a point's position")
        colours[p] = lines.numbers(3, "a point's colour 'r g b'")
        at = lines.at + 1
        views.append(lines.views())
        cams = views[-1][:, 0]
        if np.any((cams < 0) | (cams >= n_cameras) | (cams != np.round(cams))):
            raise UserError(f"{path} line {at}: a view names a camera outside 0..{n_cameras - 1}")
    return Bundle(tuple(cameras), points, colours, tuple(views))


def read_keys(path: str | Path) -> Keys:
    """Lowe's keypoints of one image from ``path`` (``.key`` or gzipped ``.key.gz``)."""
    path = Path(path)
    try:
        opener = gzip.open if path.suffix == ".gz" else open
        with opener(path, "rt") as fh:
            text = fh.read()
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read the key file {path}: {exc}") from None
    head, _, body = text.partition("\n")
    try:
        count, length = (int(v) for v in head.split())
        values = np.array(body.split(), dtype=np.float64)
    except ValueError:
        raise UserError(f"{path}: expected Lowe's key format ('<keys> <length>' then numbers)") from None
    if count < 0 or length <= 0 or values.size != count * (4 + length) or not np.all(np.isfinite(values)):
        raise UserError(f"{path}: expected {count} keypoints of 4 + {length} numbers each, "
                        f"got {values.size} numbers")
    table = values.reshape(count, 4 + length)
    descriptors = table[:, 4:]
    if np.any((descriptors < 0) | (descriptors > 255) | (descriptors != np.round(descriptors))):
        raise UserError(f"{path}: descriptor entries must be integers 0-255")
    return Keys(table[:, 0].copy(), table[:, 1].copy(), table[:, 2].copy(), table[:, 3].copy(),
                descriptors.astype(np.uint8))
