"""A recorded range-bearing log: the Victoria Park text format (GTSAM's ``Data/victoria_park.txt``),
also a user's own log's. One record a line, ``#`` comments::

    ODOMETRY i j dx dy dθ  cxx cxy cxθ cyy cyθ cθθ
    LANDMARK k ref x y  sxx sxy syy

* ``ODOMETRY``: pose ``i`` to ``j`` by ``(dx, dy, dθ)`` in pose ``i``'s frame (m, rad; x forward, y
  left), the covariance as its upper triangle in g2o order. Poses form one chain (``j > i``, each
  ``i`` the previous ``j``) from the origin ``(0, 0, 0)``.
* ``LANDMARK``: from pose ``k`` (the current one) a landmark seen at ``(x, y)`` in the robot frame,
  covariance ``[[sxx, sxy], [sxy, syy]]`` (m²); ``ref`` its reference id (a non-negative integer,
  distinct within a pose) or ``-``.

A bad log is refused in one line naming file, line and field (``LogError``). A sighting becomes
``z = (r, φ) = h((0, 0, 0), (x, y))`` with ``R = G Σ Gᵀ``, ``G = ∂h/∂l`` (first order). The reader
knows the format, not the tracks, so anything can read a log.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..models.range_bearing import jacobians, predict

ODOMETRY_FIELDS = ("i", "j", "dx", "dy", "dθ", "cxx", "cxy", "cxθ", "cyy", "cyθ", "cθθ")
LANDMARK_FIELDS = ("k", "ref", "x", "y", "sxx", "sxy", "syy")
FIELDS = {"ODOMETRY": ODOMETRY_FIELDS, "LANDMARK": LANDMARK_FIELDS}
NO_REFERENCE = "-"   # a sighting without a reference id
MIN_RANGE = 1e-6     # m: a sighting at the sensor itself has no bearing


class LogError(UserError):
    """A log the reader refuses: one line naming the file, the line and the field."""


@dataclass(frozen=True)
class RangeBearingLog:
    """A parsed log, ``N`` poses and ``S`` sightings.

    pose_ids: (N,) the log's pose ids in order.
    increments: (N−1, 3) ``(dx, dy, dθ)`` from pose n to n+1 in pose n's frame.
    increment_covariances: (N−1, 3, 3).
    sighting_pose: (S,) the pose index of each sighting, non-decreasing.
    sighting_ref: (S,) its reference id, −1 for none.
    sighting_xy: (S, 2) in the robot frame (m).
    sighting_covariances: (S, 2, 2) (m²).
    digest: the parsed bytes' ``file_digest``."""

    name: str
    digest: str
    pose_ids: np.ndarray
    increments: np.ndarray
    increment_covariances: np.ndarray
    sighting_pose: np.ndarray
    sighting_ref: np.ndarray
    sighting_xy: np.ndarray
    sighting_covariances: np.ndarray

    def range_bearing(self) -> tuple[np.ndarray, np.ndarray]:
        """Every sighting as ``z = (r, φ)`` (S, 2) with ``R = G Σ Gᵀ`` (S, 2, 2) (module docstring)."""
        origin = np.zeros(3)
        z = predict(origin, self.sighting_xy).reshape(-1, 2)
        G = jacobians(origin, self.sighting_xy)[1].reshape(-1, 2, 2)
        R = G @ self.sighting_covariances @ np.swapaxes(G, 1, 2)
        return z, 0.5 * (R + np.swapaxes(R, 1, 2))


class _Reader:
    """The state of one pass over a log's lines (``read_log``)."""

    def __init__(self, path: Path) -> None:
        self.path, self.number = path, 0
        self.pose_ids: list[int] = []
        self.odometry: list[list[float]] = []
        self.sightings: list[tuple[int, int, list[float]]] = []
        self.refs_here: set[int] = set()

    def fail(self, field: str, why: str) -> LogError:
        return LogError(f"{self.path} line {self.number}, field {field}: {why}")

    def integer(self, text: str, field: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise self.fail(field, f"expected an integer id, got {text!r}") from None
        if value < 0:
            raise self.fail(field, f"ids are non-negative integers, got {value}")
        return value

    def numbers(self, texts: list[str], fields: tuple[str, ...]) -> list[float]:
        values = []
        for text, field in zip(texts, fields):
            try:
                value = float(text)
            except ValueError:
                raise self.fail(field, f"expected a number, got {text!r}") from None
            if not math.isfinite(value):
                raise self.fail(field, f"must be finite, got {text!r}")
            values.append(value)
        return values

    def line(self, parts: list[str]) -> None:
        kind = parts[0]
        if kind not in FIELDS:
            raise self.fail("kind", f"expected ODOMETRY or LANDMARK, got {kind!r}")
        fields = FIELDS[kind]
        if len(parts) - 1 != len(fields):
            missing = fields[len(parts) - 1] if len(parts) - 1 < len(fields) else None
            what = f"{missing} is missing" if missing else f"{len(parts) - 1 - len(fields)} extra column(s)"
            raise self.fail(missing or fields[-1], f"{kind} takes {len(fields)} fields ({' '.join(fields)}): {what}")
        (self.odometry_line if kind == "ODOMETRY" else self.landmark_line)(parts[1:])

    def odometry_line(self, parts: list[str]) -> None:
        i, j = self.integer(parts[0], "i"), self.integer(parts[1], "j")
        values = self.numbers(parts[2:], ODOMETRY_FIELDS[2:])
        if not self.pose_ids:
            self.pose_ids.append(i)
        elif i != self.pose_ids[-1]:
            raise self.fail("i", f"pose {i} does not continue the odometry chain, which is at pose {self.pose_ids[-1]}")
        if j <= i:
            raise self.fail("j", f"pose ids must increase along the chain, got {i} -> {j}")
        c = values[3:]
        cov = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]])
        if not positive_definite(cov):
            raise self.fail("cxx..cθθ", "the odometry covariance is not positive definite")
        self.pose_ids.append(j)
        self.odometry.append(values)
        self.refs_here = set()

    def landmark_line(self, parts: list[str]) -> None:
        k = self.integer(parts[0], "k")
        ref = -1 if parts[1] == NO_REFERENCE else self.integer(parts[1], "ref")
        x, y, sxx, sxy, syy = self.numbers(parts[2:], LANDMARK_FIELDS[2:])
        if not self.pose_ids:
            self.pose_ids.append(k)
        elif k != self.pose_ids[-1]:
            raise self.fail("k", f"a sighting is made from the pose the robot is at ({self.pose_ids[-1]}), got {k}")
        if math.hypot(x, y) < MIN_RANGE:
            raise self.fail("x, y", "a sighting at the sensor itself has no bearing")
        if not positive_definite(np.array([[sxx, sxy], [sxy, syy]])):
            raise self.fail("sxx..syy", "the sighting covariance is not positive definite")
        if ref >= 0 and ref in self.refs_here:
            raise self.fail("ref", f"reference id {ref} is sighted twice from pose {k} (one landmark, one sighting a pose)")
        self.refs_here.add(ref)
        self.sightings.append((len(self.pose_ids) - 1, ref, [x, y, sxx, sxy, syy]))


def positive_definite(cov: np.ndarray) -> bool:
    """Whether the symmetric ``cov`` is positive definite (its Cholesky factor exists)."""
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return False
    return True


def read_log(path: str | Path) -> RangeBearingLog:
    """Parse and check the log at ``path`` (module docstring); a ``LogError`` names what is wrong."""
    path = Path(path)
    try:
        data = path.read_bytes()
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise LogError(f"{path}: no such log file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LogError(f"{path}: cannot be read as a text log ({type(exc).__name__}: {exc})") from None
    reader = _Reader(path)
    for reader.number, line in enumerate(text.splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if parts:
            reader.line(parts)
    if not reader.pose_ids:
        raise LogError(f"{path} line {reader.number}, field kind: the log holds no ODOMETRY or LANDMARK line")
    return _arrays(reader, path, hashlib.sha256(data).hexdigest()[:16])


def _arrays(reader: _Reader, path: Path, digest: str) -> RangeBearingLog:
    odometry = np.array(reader.odometry, dtype=np.float64).reshape(-1, 9)
    c = odometry[:, 3:]
    cov = np.stack([c[:, 0], c[:, 1], c[:, 2], c[:, 1], c[:, 3], c[:, 4], c[:, 2], c[:, 4], c[:, 5]], axis=1)
    s = np.array([v for _, _, v in reader.sightings], dtype=np.float64).reshape(-1, 5)
    scov = np.stack([s[:, 2], s[:, 3], s[:, 3], s[:, 4]], axis=1).reshape(-1, 2, 2)
    return RangeBearingLog(
        name=path.stem, digest=digest, pose_ids=np.array(reader.pose_ids, dtype=np.int64),
        increments=odometry[:, :3].copy(), increment_covariances=cov.reshape(-1, 3, 3),
        sighting_pose=np.array([k for k, _, _ in reader.sightings], dtype=np.int64),
        sighting_ref=np.array([r for _, r, _ in reader.sightings], dtype=np.int64),
        sighting_xy=s[:, :2].copy(), sighting_covariances=scov)
